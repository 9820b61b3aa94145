"""Tests of imunoise.noise.wv: Haar wavelet variance against R simts, allantools, exact pooling identities."""

from __future__ import annotations

import json

import allantools
import numpy as np
import pytest
from scipy.stats import chi2

from imunoise.errors import DataError
from imunoise.noise.wv import (
    HUBER_C,
    MIN_COEFFICIENTS,
    WaveletVariance,
    WVAccumulator,
    diagonal_weights,
    huber_efficiency,
    huber_scale,
    wavelet_variance,
)


def _rel(a, b):
    return np.max(np.abs(np.asarray(a) / np.asarray(b) - 1.0))


@pytest.fixture
def simts_case(shared_data):
    x = np.load(shared_data("simts_reference", "sim_2ar1_wn_rw_N100000.npy"))
    ref = np.genfromtxt(shared_data("simts_reference", "simts_wv.csv"), delimiter=",", names=True)
    return x, ref


# 1. R simts, number for number -----------------------------------------------------------------------


def test_matches_simts_wv_and_eta3_ci(simts_case):
    x, ref = simts_case
    wv = wavelet_variance(x, freq=1.0)
    assert len(wv) == 16 == len(ref)
    np.testing.assert_array_equal(wv.levels, ref["level"].astype(int))
    np.testing.assert_array_equal(wv.scales, ref["tau"])
    np.testing.assert_array_equal(wv.n_coefficients, x.size - 2 ** wv.levels + 1)
    assert _rel(wv.variance, ref["wv"]) < 1e-12
    assert _rel(wv.ci_low, ref["ci_low"]) < 1e-10
    assert _rel(wv.ci_high, ref["ci_high"]) < 1e-10
    # simts' "fast" Omega is 1/(ci_high - ci_low)^2
    assert _rel(diagonal_weights(wv), ref["omega_diag"]) < 1e-8


def test_default_level_rule_keeps_all_simts_levels_and_drops_near_empty_tops():
    # N = 1e5: M_16 = 34465 >= MIN_COEFFICIENTS, so all floor(log2 N) levels are kept (checked above);
    # N = 2**10 exactly: M_10 = 1 < MIN_COEFFICIENTS, dropped unless min_coefficients=1 (simts' set)
    x = np.random.default_rng(3).standard_normal(2**10)
    assert wavelet_variance(x, freq=1.0).levels.tolist() == list(range(1, 10))
    full = wavelet_variance(x, min_coefficients=1, freq=1.0)
    assert full.levels.tolist() == list(range(1, 11)) and full.n_coefficients[-1] == 1
    assert wavelet_variance(x, levels=4, freq=1.0).levels.tolist() == [1, 2, 3, 4]
    assert wavelet_variance(x, levels=40, freq=1.0).levels.tolist() == list(range(1, 10))
    assert MIN_COEFFICIENTS <= 34465


# 2. Allan variance identity ----------------------------------------------------------------------------


@pytest.mark.parametrize("n", [4099, 20000])
def test_twice_wv_is_overlapping_allan_variance(n):
    rng = np.random.default_rng(n)
    x = 1e3 + rng.standard_normal(n) + 0.01 * np.cumsum(rng.standard_normal(n))  # offset and drift
    wv = wavelet_variance(x, freq=100.0)
    m = (wv.scales / 2).astype(int)
    taus, adev, _, _ = allantools.oadev(x, rate=1.0, data_type="freq", taus=m.astype(float))
    np.testing.assert_array_equal(taus, m)
    assert _rel(2.0 * wv.variance, adev**2) < 1e-10
    t_s, avar = wv.avar()
    np.testing.assert_allclose(t_s, m / 100.0)
    np.testing.assert_allclose(wv.scales_s, wv.scales / 100.0)
    assert _rel(avar, adev**2) < 1e-10


# 3. streaming accumulator = batch ---------------------------------------------------------------------


def _random_segments(seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    lengths = [3000, 17, 1, 2, 513, 8192, 700, 40000, 5]
    return [rng.normal(10.0 * k, 1.0 + k, size=n) + 0.05 * np.cumsum(rng.standard_normal(n))
            for k, n in enumerate(lengths)]


def _assert_same(a: WaveletVariance, b: WaveletVariance, rtol: float = 1e-10) -> None:
    np.testing.assert_array_equal(a.scales, b.scales)
    np.testing.assert_array_equal(a.n_coefficients, b.n_coefficients)
    for name in ("variance", "ci_low", "ci_high", "cov"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=rtol, atol=0, err_msg=name)


def test_accumulator_equals_batch_on_segments():
    segs = _random_segments(1)
    acc = WVAccumulator(freq=200.0)
    for s in segs:
        acc.add(s)
    assert acc.n_segments == len(segs) and acc.n_samples == sum(map(len, segs))
    res = acc.result()
    batch = wavelet_variance(segs, freq=200.0)
    _assert_same(res, batch)
    assert res.freq == 200.0 and res.levels[-1] == int(np.log2(40000))
    # result() can be called between adds: it reflects the segments so far
    acc2 = WVAccumulator(levels=6)
    acc2.add(segs[0])
    _assert_same(acc2.result(), wavelet_variance(segs[:1], levels=6, freq=1.0))
    acc2.add(segs[3])
    _assert_same(acc2.result(), wavelet_variance([segs[0], segs[3]], levels=6, freq=1.0))


def test_accumulator_with_one_segment_equals_batch_on_array():
    x = np.random.default_rng(2).standard_normal(12345)
    acc = WVAccumulator()
    acc.add(x)
    _assert_same(acc.result(), wavelet_variance(x, freq=1.0))


# 4. segments never cross junctions --------------------------------------------------------------------


def test_pooled_segments_ignore_a_huge_offset_between_them():
    rng = np.random.default_rng(4)
    a, b = rng.standard_normal(5000), 1e6 + 3.0 * rng.standard_normal(3000)
    pooled = wavelet_variance([a, b], freq=1.0)
    wa, wb = wavelet_variance(a, freq=1.0), wavelet_variance(b, freq=1.0)
    k = len(wb)  # levels both segments have
    assert pooled.levels.tolist() == wa.levels.tolist()
    by_hand_m = wa.n_coefficients[:k] + wb.n_coefficients
    by_hand = (wa.variance[:k] * wa.n_coefficients[:k] + wb.variance * wb.n_coefficients) / by_hand_m
    np.testing.assert_array_equal(pooled.n_coefficients[:k], by_hand_m)
    assert _rel(pooled.variance[:k], by_hand) < 1e-10
    assert _rel(pooled.variance[k:], wa.variance[k:]) < 1e-12  # only segment a reaches these levels
    # the paper's way (concatenate) sees the 1e6 step at every level
    joined = wavelet_variance([a, b], concat=True, freq=1.0)
    assert np.all(joined.variance[:k] > 100 * pooled.variance[:k])
    assert joined.n_coefficients[0] == 7999


# 5. CIs, covariance, robust estimate ------------------------------------------------------------------


def test_eta3_chi_square_interval():
    x = np.random.default_rng(5).standard_normal(3000)
    for alpha in (0.05, 0.32):
        wv = wavelet_variance(x, alpha=alpha, freq=1.0)
        eta = np.maximum(wv.n_coefficients / wv.scales, 1.0)
        np.testing.assert_allclose(wv.ci_low, eta * wv.variance / chi2.ppf(1 - alpha / 2, eta), rtol=1e-12)
        np.testing.assert_allclose(wv.ci_high, eta * wv.variance / chi2.ppf(alpha / 2, eta), rtol=1e-12)
        assert np.all((wv.ci_low < wv.variance) & (wv.variance < wv.ci_high))
    # relatively wider where fewer coefficients count
    assert np.all(np.diff((wv.ci_high - wv.ci_low) / wv.variance) > 0)


def test_white_noise_wv_and_covariance_calibration():
    # WN sigma^2 = 4: nu^2_j = 4/tau_j; the diagonal cov matches the Monte Carlo variance of nu^2 hat
    rng = np.random.default_rng(6)
    est = np.array([wavelet_variance(2.0 * rng.standard_normal(4096), levels=6, freq=1.0).variance for _ in range(150)])
    cov = wavelet_variance(2.0 * rng.standard_normal(4096), levels=6, freq=1.0).cov
    truth = 4.0 / 2.0 ** np.arange(1, 7)
    se = est.std(axis=0) / np.sqrt(len(est))
    assert np.all(np.abs(est.mean(axis=0) - truth) < 4 * se)
    ratio = np.diag(cov) / est.var(axis=0)
    assert np.all((ratio > 0.5) & (ratio < 2.0)), ratio


def test_cov_positive_definite_and_finite_for_short_or_periodic_data():
    for x in (np.random.default_rng(7).standard_normal(16), np.tile([1.0, -1.0], 64), np.arange(40.0)):
        wv = wavelet_variance(x, min_coefficients=1, freq=1.0)
        assert np.all(np.isfinite(wv.cov)) and np.all(np.isfinite(wv.variance))
        assert np.linalg.eigvalsh(wv.cov).min() > 0
        np.testing.assert_array_equal(wv.cov, np.diag(np.diag(wv.cov)))


def test_huber_constant_gives_60_percent_efficiency_and_consistency():
    assert abs(huber_efficiency() - 0.6) < 1e-9 and abs(HUBER_C - 1.2245) < 1e-4
    z = np.random.default_rng(8).standard_normal(400_000) * 3.0
    assert abs(huber_scale(z) / 9.0 - 1.0) < 0.01


def test_robust_close_to_classical_on_clean_data_and_resists_outliers():
    rng = np.random.default_rng(9)
    x = rng.standard_normal(2**17)
    clean, robust = wavelet_variance(x, levels=6, freq=1.0), wavelet_variance(x, levels=6, robust=True, freq=1.0)
    assert robust.robust and not clean.robust
    assert _rel(robust.variance, clean.variance) < 0.05
    truth = 1.0 / clean.scales
    y = x.copy()
    y[rng.choice(y.size, 100, replace=False)] += 50.0 * rng.choice([-1.0, 1.0], 100)
    cl, rb = wavelet_variance(y, levels=6, freq=1.0), wavelet_variance(y, levels=6, robust=True, freq=1.0)
    err_cl, err_rb = np.abs(cl.variance / truth - 1), np.abs(rb.variance / truth - 1)
    # each spike touches tau_j coefficients, so the contaminated share grows with the level
    assert np.all(err_rb[:5] < 0.1), err_rb
    assert np.all(err_cl > 5 * err_rb) and np.all(err_cl > 1.0)
    assert np.all(np.isfinite(rb.cov)) and np.all(np.diag(rb.cov) > 0)


# result object --------------------------------------------------------------------------------------


def test_json_round_trip_and_subset():
    wv = wavelet_variance([np.random.default_rng(10).standard_normal(999), np.arange(50.0) ** 0.5],
                          freq=125.0, alpha=0.1, robust=True)
    back = WaveletVariance.from_dict(json.loads(json.dumps(wv.to_dict())))
    assert back == wv and back.freq == 125.0 and back.robust and back.alpha == 0.1
    sub = wv.subset(wv.levels % 2 == 1)
    assert sub.levels.tolist() == [1, 3, 5, 7, 9]
    np.testing.assert_array_equal(sub.cov, wv.cov[np.ix_([0, 2, 4, 6, 8], [0, 2, 4, 6, 8])])
    assert wv.subset([0, 1]).levels.tolist() == [1, 2]
    with pytest.raises(DataError, match="mask"):
        wv.subset(np.ones(3, dtype=bool))


# 6. bad input -----------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("data", "kwargs", "match"),
    [
        (np.r_[np.ones(100), np.nan, np.ones(9)], {}, "index 100"),
        (np.r_[np.zeros(20), np.inf], {}, r"non-finite value \(inf\) at index 20"),
        ([np.arange(30.0), np.r_[1.0, np.nan]], {}, "segment 1.*index 1"),
        (np.arange(15.0), {}, "at least 16"),
        (np.full(100, 3.5), {}, "all samples equal"),
        ([np.full(50, 1.0), np.full(50, 2.0)], {}, "all samples equal within every segment"),
        (np.zeros((100, 3)), {}, "pass one axis"),
        ([], {}, "no segments"),
        (np.arange(100.0), {"levels": 0}, "levels"),
        (np.arange(100.0), {"alpha": 1.5}, "alpha"),
        (["a", "b"], {}, "not numeric"),
    ],
)
def test_bad_input_raises_data_error(data, kwargs, match):
    with pytest.raises(DataError, match=match):
        wavelet_variance(data, **{"freq": 1.0, **kwargs})


def test_accumulator_bad_input():
    acc = WVAccumulator()
    with pytest.raises(DataError, match="at least 16"):
        acc.result()
    with pytest.raises(DataError, match="index 2"):
        acc.add(np.array([1.0, 2.0, np.nan]))
    with pytest.raises(DataError, match="pass one axis"):
        acc.add(np.zeros((4, 4)))


def test_scale_runs_are_the_runs_of_true():
    # the one run finder of band_departures and the Allan line readings: exact (first, last) per run
    from imunoise.noise.wv import scale_runs

    assert scale_runs(np.array([], dtype=bool)) == []
    assert scale_runs(np.array([False, False])) == []
    assert scale_runs(np.array([True, True, True])) == [(0, 2)]
    assert scale_runs(np.array([False, True, True, False, True])) == [(1, 2), (4, 4)]
    assert scale_runs(np.array([True, False, False, True, True, False])) == [(0, 0), (3, 4)]
    rng = np.random.default_rng(7)
    m = rng.random(200) < 0.5
    runs = scale_runs(m)
    covered = np.zeros(m.size, dtype=bool)
    for a, b in runs:
        assert m[a : b + 1].all() and (a == 0 or not m[a - 1]) and (b == m.size - 1 or not m[b + 1])
        covered[a : b + 1] = True
    assert np.array_equal(covered, m)
