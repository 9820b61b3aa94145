"""Tests of imunoise.noise.wv_stream: a contiguous series streamed in chunks gives the batch wavelet variance."""

from __future__ import annotations

import numpy as np
import pytest

from imunoise.errors import DataError
from imunoise.noise.wv import WaveletVariance, WVAccumulator, wavelet_variance
from imunoise.noise.wv_stream import BLOCK, WVStream

RTOL = 1e-9


def _series(n: int, seed: int, offset: float = 3.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return offset + rng.standard_normal(n) + 0.02 * np.cumsum(rng.standard_normal(n))


def _stream(x: np.ndarray, cuts, **kw) -> WVStream:
    s = WVStream(**{"freq": 1.0, **kw})
    edges = [0, *sorted(int(c) for c in cuts), x.shape[0]]
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        s.add(x[a:b])
    return s


def _assert_same(got: WaveletVariance, ref: WaveletVariance) -> None:
    np.testing.assert_array_equal(got.scales, ref.scales)
    np.testing.assert_array_equal(got.n_coefficients, ref.n_coefficients)
    for name in ("variance", "ci_low", "ci_high"):
        np.testing.assert_allclose(getattr(got, name), getattr(ref, name), rtol=RTOL, atol=0, err_msg=name)
    np.testing.assert_allclose(np.diag(got.cov), np.diag(ref.cov), rtol=RTOL, atol=0, err_msg="cov")
    assert np.count_nonzero(got.cov - np.diag(np.diag(got.cov))) == 0
    assert (got.freq, got.alpha, got.robust) == (ref.freq, ref.alpha, ref.robust)


# 1. equal to the batch estimate, however the series is cut ----------------------------------------


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_chunkings_equal_the_batch(seed):
    rng = np.random.default_rng(seed)
    n = 5000 + int(rng.integers(1, 3000))  # not a power of two
    x = _series(n, seed)
    cuts = rng.choice(np.arange(1, n), size=int(rng.integers(1, 60)), replace=False)
    cuts = np.concatenate([cuts, cuts[:5]])  # repeated cuts: empty chunks
    s = _stream(x, cuts, freq=200.0)
    ref = wavelet_variance(x, freq=200.0)
    assert len(ref) == 12
    _assert_same(s.result(), ref)


def test_one_sample_chunks_and_cuts_at_powers_of_two():
    x = _series(3001, 7)
    ref = wavelet_variance(x, alpha=0.1, freq=1.0)
    _assert_same(_stream(x, range(1, x.shape[0]), alpha=0.1).result(), ref)
    _assert_same(_stream(x, [2**k for k in range(12)], alpha=0.1).result(), ref)
    _assert_same(_stream(x, [2**k - 1 for k in range(1, 12)], alpha=0.1).result(), ref)
    scalar = WVStream(alpha=0.1, freq=1.0)
    for v in x:
        scalar.add(v)  # a numpy scalar is one sample
    _assert_same(scalar.result(), ref)


def test_chunks_longer_than_a_block_and_result_midway():
    x = _series(3 * BLOCK + 123, 11)
    s = WVStream(freq=1.0)
    s.add(x[: 2 * BLOCK + 5])
    _assert_same(s.result(), wavelet_variance(x[: 2 * BLOCK + 5], freq=1.0))  # result() leaves the stream intact
    s.add(x[2 * BLOCK + 5 :])
    _assert_same(s.result(), wavelet_variance(x, freq=1.0))
    assert s.n_samples == x.shape[0]


def test_fixed_levels_and_max_scale_s():
    x = _series(4321, 5)
    cuts = [100, 1024, 1025, 3000]
    _assert_same(_stream(x, cuts, levels=6).result(), wavelet_variance(x, levels=6, freq=1.0))
    # more levels asked than the data hold: the batch rule floor(log2 N) caps it
    _assert_same(_stream(x, cuts, levels=30).result(), wavelet_variance(x, levels=30, freq=1.0))
    # 0.64 s at 100 Hz = 64 samples = 2**6; 0.7 s also gives 6 (2**7 = 1.28 s is too coarse)
    for max_scale_s in (0.64, 0.7):
        got = _stream(x, cuts, freq=100.0, max_scale_s=max_scale_s).result()
        _assert_same(got, wavelet_variance(x, levels=6, freq=100.0))
        assert got.scales_s[-1] <= max_scale_s


def test_all_levels_of_an_exact_power_of_two_with_min_coefficients_one():
    x = _series(2**11, 8)
    ref = wavelet_variance(x, min_coefficients=1, freq=1.0)
    assert ref.n_coefficients[-1] == 1 and len(ref) == 11
    _assert_same(_stream(x, [3, 1000], min_coefficients=1).result(), ref)


def test_matches_simts_reference(shared_data):
    x = np.load(shared_data("simts_reference", "sim_2ar1_wn_rw_N100000.npy"))
    ref = np.genfromtxt(shared_data("simts_reference", "simts_wv.csv"), delimiter=",", names=True)
    wv = _stream(x, np.arange(1, x.shape[0], 7919)).result()
    np.testing.assert_array_equal(wv.levels, ref["level"].astype(int))
    np.testing.assert_allclose(wv.variance, ref["wv"], rtol=1e-10, atol=0)
    np.testing.assert_allclose(wv.ci_high, ref["ci_high"], rtol=1e-10, atol=0)


def test_long_series_with_large_offset_keeps_the_digits():
    # accelerometer-like: 9.81 m/s^2 offset, 1e-3 noise, a slow drift; the first chunk is one sample, so
    # the subtracted constant is far from the mean of the whole series
    rng = np.random.default_rng(4)
    n = 2**21 + 12345
    x = 9.81 + 1e-3 * rng.standard_normal(n) + 1e-6 * np.cumsum(rng.standard_normal(n)) + np.linspace(0, 0.5, n)
    ref = wavelet_variance(x, freq=1.0)
    assert len(ref) == 21
    _assert_same(_stream(x, [1, *range(1, n, 300_007)]).result(), ref)


def test_columns_are_independent_series():
    rng = np.random.default_rng(9)
    scale = np.array([1e-3, 2e-3, 5e-4, 0.05, 0.04, 0.06])
    x = np.array([0.0, 1e-2, -3e-3, 0.1, -0.2, 9.81]) + rng.standard_normal((2500, 6)) * scale
    s = _stream(x, [1, 2, 700, 2048], freq=100.0, levels=9)
    got = s.result()
    assert isinstance(got, list) and len(got) == 6 and s.n_columns == 6
    for k in range(6):
        _assert_same(got[k], wavelet_variance(x[:, k], freq=100.0, levels=9))


def test_contiguous_stream_keeps_the_levels_that_pooled_chunks_lose():
    x = _series(8192 + 100, 12)
    pooled = WVAccumulator()
    for c in np.array_split(x, 64):  # 64 chunks of ~130 samples: pooled as separate stops
        pooled.add(c)
    assert len(pooled.result()) == 7  # floor(log2 130)
    assert len(_stream(x, np.cumsum([len(c) for c in np.array_split(x, 64)])[:-1]).result()) == 13


# 2. memory: set by the coarsest level, not by N ------------------------------------------------------


def test_buffer_is_bounded_by_the_top_level_not_by_n():
    lengths = {}
    for n in (2**12 + 3, 2**16 + 3):
        for kw in ({"levels": 8}, {"max_scale_s": 2.56, "freq": 100.0}):
            s = _stream(_series(n, 1), [n // 3], **kw)
            lengths[n, tuple(kw)] = s.buffer_len
            assert s.buffer_len == 2**8 - 1  # rings of levels 1..8: 1 + 2 + ... + 128 window sums
            assert all(w.shape == (BLOCK,) for w in s._work)
    assert len(set(lengths.values())) == 1
    # without a cap the rings are ready for level floor(log2 N) + 1: at most 2N - 1 values
    for n in (1000, 1024, 1025, 70_000):
        s = WVStream(freq=1.0)
        s.add(_series(n, 2))
        top = int(np.floor(np.log2(n)))
        assert s.buffer_len == 2 ** (top + 1) - 1 <= 2 * n - 1
    # short capped stream: rings are created only as their first window sum arrives
    s = WVStream(levels=20, freq=1.0)
    s.add(_series(100, 3))
    assert s.buffer_len == 2**7 - 1


# 3. errors ------------------------------------------------------------------------------------------


def test_bad_samples_are_located():
    s = WVStream(freq=1.0)
    s.add(np.ones(10))
    x = np.zeros(5)
    x[3] = np.nan
    with pytest.raises(DataError, match="index 13 of the stream"):
        s.add(x)
    m = WVStream(freq=1.0)
    bad = np.zeros((4, 3))
    bad[2, 1] = np.inf
    with pytest.raises(DataError, match="index 2, column 1"):
        m.add(bad)
    with pytest.raises(DataError, match="not numeric"):
        WVStream(freq=1.0).add(["a", "b"])


def test_shape_must_stay_the_same():
    s = WVStream(freq=1.0)
    s.add(np.zeros((5, 3)))
    s.add(np.zeros((0, 3)))
    with pytest.raises(DataError, match=r"\(n, 3\)"):
        s.add(np.zeros((5, 2)))
    with pytest.raises(DataError, match=r"\(n, 3\)"):
        s.add(np.zeros(5))
    with pytest.raises(DataError, match="shape"):
        WVStream(freq=1.0).add(np.zeros((2, 2, 2)))


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"levels": 0}, "levels must be a positive integer"),
        ({"levels": 2.5}, "levels must be a positive integer"),
        ({"levels": True}, "levels must be a positive integer"),
        ({"levels": 4, "max_scale_s": 1.0}, "not both"),
        ({"max_scale_s": -1.0}, "max_scale_s must be a positive time"),
        ({"max_scale_s": float("nan")}, "max_scale_s must be a positive time"),
        ({"max_scale_s": 0.01, "freq": 100.0}, "below the finest scale 2/freq = 0.02 s"),
        ({"freq": 0.0}, "freq must be a finite rate > 0"),
        ({}, r"WVStream needs the sample rate of the data: give freq=HZ"),
        ({"alpha": 1.0}, "alpha"),
        ({"min_coefficients": 0}, "min_coefficients"),
    ],
)
def test_bad_arguments(kw, match):
    with pytest.raises(DataError, match=match):
        WVStream(**({"freq": 1.0, **kw} if kw else {}))  # {}: no rate at all


def test_too_little_or_constant_data():
    s = WVStream(freq=1.0)
    s.add(np.arange(15.0))
    with pytest.raises(DataError, match="only 15 samples"):
        s.result()
    c = WVStream(freq=1.0)
    c.add(np.full(100, 2.5))
    with pytest.raises(DataError, match="all samples equal"):
        c.result()
    m = WVStream(freq=1.0)
    m.add(np.column_stack([np.arange(100.0), np.full(100, 1.0)]))
    with pytest.raises(DataError, match="column 1"):
        m.result()
