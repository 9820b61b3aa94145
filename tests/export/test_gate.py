"""The pair gate: the true pair passes its own data, a pair 3× off in density is refused with its side, the
inflation that bounds the data and the data's reading; a kept line names the cause."""

import math

import numpy as np
import pytest

from imunoise.export.gate import TOLERANCE, data_reading, pair_gate
from imunoise.noise.wv import wavelet_variance

F = 100.0
N, K = 1.0e-3, 2.0e-4


@pytest.fixture(scope="module")
def wv():
    rng = np.random.default_rng(3740)
    n = 2**18
    x = N * math.sqrt(F) * rng.standard_normal(n) + np.cumsum(K / math.sqrt(F) * rng.standard_normal(n))
    return wavelet_variance(x, freq=F)


def test_the_true_pair_passes_its_data_and_the_reading_finds_it(wv):
    g = pair_gate(wv, N, K)
    assert not g.refused and g.worst_ratio < TOLERANCE and g.cause == ""
    assert g.tau_range_s[0] == pytest.approx(0.04)
    n_read, k_read = data_reading(wv)
    assert n_read == pytest.approx(N, rel=0.05)
    assert 0.3 * K < k_read < 3 * K


def test_an_overconfident_pair_is_reported_with_side_inflation_and_the_closest_pair(wv):
    g = pair_gate(wv, N / 3, K / 3)
    assert not g.refused and not g.above  # a pair exists that stands for the data: this one is reported
    assert g.worst_ratio == pytest.approx(9.0, rel=0.3)
    assert g.inflation == pytest.approx(3.0, rel=0.2)
    assert g.best[2] < TOLERANCE and g.best[0] == pytest.approx(N, rel=0.1)
    assert "the pair closest to the data" in g.text()


def test_data_no_pair_stands_for_is_refused_with_the_line_named_and_the_reading(wv):
    rng = np.random.default_rng(3741)
    n = 2**16
    t = np.arange(n) / F
    x = N * math.sqrt(F) * rng.standard_normal(n) + 0.05 * np.sin(2 * np.pi * 31.0 * t)
    vib = wavelet_variance(x, freq=F)
    g = pair_gate(vib, N, K, lines=[{"freq_hz": 31.0, "share": 0.9}])
    assert g.refused and g.best[2] > TOLERANCE
    assert g.cause.startswith("vibration at 31 Hz (90 % of the variance) dominates T < ")
    assert g.reading == data_reading(vib)
    assert "what --force writes" in g.text() and g.to_dict()["refused"] is True
    assert not pair_gate(wv, 3 * N, K).refused


def test_the_update_interval_and_horizon_bound_the_range(wv):
    g = pair_gate(wv, N, K, update_interval_s=0.5, horizon_s=20.0)
    assert 0.5 <= g.tau_range_s[0] < 1.3 and 10.0 < g.tau_range_s[1] <= 20.0
