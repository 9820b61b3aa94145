"""Paired statistics for overlapping windows (imunoise.experiments.stats): identities and CI coverage."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from imunoise.errors import DataError
from imunoise.experiments.stats import (
    block_bootstrap_interval,
    bootstrap_ratio,
    default_block,
    drive_log_ratios,
    gain_share,
    log_ratios,
    n_independent,
    paired_entry,
    politis_white_block,
)


def _overlap_series(rng, n, mean, lag=3, scale=0.1):
    # windows of L = lag·S: each window's log-ratio sums the effects of `lag` consecutive S-long stretches
    e = rng.normal(size=n + lag - 1)
    return mean + scale * np.convolve(e, np.ones(lag), mode="valid")


def test_identical_methods_give_ratio_one_and_degenerate_ci():
    vals = {"a": [[10.0, 20.0, 30.0, 5.0]], "b": [[10.0, 20.0, 30.0, 5.0]]}
    e = paired_entry("a", "b", "drift", vals, 3, n_independent_total=2, n_boot=200)
    assert e["ratio"] == 1.0 and e["ci"] == [1.0, 1.0]
    assert not e["significant"] and e["n_windows"] == 4 and e["n_drives"] == 1


def test_constant_ratio_is_exact_and_significant():
    vals = {"a": [[20.0, 40.0, 2.0], [8.0]], "b": [[10.0, 20.0, 1.0], [4.0]]}
    e = paired_entry("a", "b", "rms", vals, 2, n_independent_total=4, n_boot=200)
    assert e["ratio"] == pytest.approx(2.0, rel=1e-12)
    assert e["ci"][0] == pytest.approx(2.0, rel=1e-12) and e["ci"][1] == pytest.approx(2.0, rel=1e-12)
    assert e["n_drives"] == 2 and e["n_windows"] == 4


def test_missing_and_nonpositive_values_are_dropped():
    lr = log_ratios([1.0, None, 0.0, 4.0, math.nan], [2.0, 1.0, 1.0, 1.0, 1.0])
    assert lr[0] == pytest.approx(math.log(0.5)) and lr[3] == pytest.approx(math.log(4.0))
    assert np.isnan(lr[[1, 2, 4]]).all()


def test_realisations_are_averaged_per_window_not_counted():
    # two noise seeds of the same two windows: log-ratios averaged per window (geometric mean of the ratios)
    a = [[2.0, 1.0], [8.0, 1.0]]
    b = [[1.0, 1.0], [1.0, 4.0]]
    lr = drive_log_ratios(a, b)
    assert lr.shape == (2,)
    assert lr[0] == pytest.approx(0.5 * (math.log(2) + math.log(8)))
    assert lr[1] == pytest.approx(0.5 * math.log(0.25))


def test_block_and_independent_counts():
    assert default_block(60, 20) == 3 and default_block(60, 60) == 1 and default_block(60, 25) == 3
    starts = np.arange(23) * 20.0
    assert n_independent(starts, 60.0) == 8  # 0, 60, ..., 420
    assert n_independent([0, 30, 59, 61], 60.0) == 2


def test_seed_reproducible():
    g = [np.random.default_rng(0).normal(0.1, 0.2, 20)]
    assert bootstrap_ratio(g, 3, seed=4, n_boot=300) == bootstrap_ratio(g, 3, seed=4, n_boot=300)


def _ar(rng, n, rho):
    e = np.empty(n)
    e[0] = rng.normal()
    for k in range(1, n):
        e[k] = rho * e[k - 1] + math.sqrt(1 - rho * rho) * rng.normal()
    return e


def test_politis_white_block_matches_its_formula_on_a_long_ar1():
    # AR(ρ), unit variance: g = (1+ρ)/(1−ρ), G = 2ρ/(1−ρ)², b_CB = (1.5 (G/g)²)^{1/3} n^{1/3} (PPW 2009)
    rho, n = 0.5, 20000
    g, big_g = (1 + rho) / (1 - rho), 2 * rho / (1 - rho) ** 2
    want = (1.5 * (big_g / g) ** 2) ** (1 / 3) * n ** (1 / 3)
    got = politis_white_block(_ar(np.random.default_rng(2), n, rho))
    assert got == pytest.approx(want, rel=0.2), (got, want)
    assert politis_white_block(np.random.default_rng(3).normal(size=n)) < 3.0  # white noise: short blocks
    assert politis_white_block(np.ones(50)) == 1.0


def test_cluster_t_interval_is_the_t_interval_of_equal_drive_means():
    rng = np.random.default_rng(5)
    groups = [rng.normal(0.1, 0.2, 10) for _ in range(6)]
    r = bootstrap_ratio(groups, 3)
    means = np.array([g.mean() for g in groups])
    half = stats.t.ppf(0.975, 5) * means.std(ddof=1) / math.sqrt(6)
    assert r["df"] == 5 and r["n_clusters"] == 6 and r["cluster"] == "drive" and r["scope"] is None
    assert math.log(r["ci"][0]) == pytest.approx(means.mean() - half, rel=1e-12)
    assert math.log(r["ci"][1]) == pytest.approx(means.mean() + half, rel=1e-12)


def test_units_are_the_clusters_above_drives():
    rng = np.random.default_rng(6)
    groups = [rng.normal(0.0, 0.1, 8) for _ in range(6)]
    r = bootstrap_ratio(groups, 3, units=["a", "a", "b", "b", "c", "c"])
    assert r["n_clusters"] == 3 and r["df"] == 2 and r["cluster"] == "unit" and r["n_drives"] == 6
    pooled = [np.concatenate(groups[i:i + 2]) for i in (0, 2, 4)]
    assert r["ci"] == pytest.approx(bootstrap_ratio(pooled, 3)["ci"], rel=1e-12)
    with pytest.raises(DataError, match="one label per drive"):
        bootstrap_ratio(groups, 3, units=["a"])


def test_one_drive_says_its_scope_and_uses_the_fixed_b_interval():
    x = 0.1 + 0.1 * _ar(np.random.default_rng(8), 100, 0.8)
    e = paired_entry("a", "b", "drift", {"a": [list(np.exp(x))], "b": [[1.0] * 100]}, 3, n_boot=500)
    assert e["scope"] == "one drive: the interval describes this drive's windows only"
    assert e["interval"] == "fixed-b t (AR(1)-calibrated)" and e["n_clusters"] == 1 and e["df"] is None
    white = paired_entry("a", "b", "drift", {"a": [list(np.exp(np.random.default_rng(8).normal(0, .1, 100)))],
                                             "b": [[1.0] * 100]}, 3, n_boot=500)
    assert white["critical"] < e["critical"]  # the AR(0.8) windows need a larger multiplier than white ones


def test_earlier_block_bootstrap_interval_is_kept_for_comparison():
    x = 0.1 * _ar(np.random.default_rng(8), 100, 0.8)
    r = block_bootstrap_interval(x, 3, n_boot=500, seed=2)
    assert 3 <= r["block"] <= 33 and r["df"] == 100 // r["block"] - 1
    assert r["ci"][0] < x.mean() < r["ci"][1] and r == block_bootstrap_interval(x, 3, n_boot=500, seed=2)


def test_window_paired_of_the_official_windows():
    from imunoise.experiments.online_exp import window_paired

    ends = {"plain": [[100.0, 200.0, 50.0]], "gmwm": [[50.0, 100.0, 25.0]], "static_var": [[100.0, 200.0, 50.0]]}
    out = window_paired(ends, [[(0.0, 60.0), (100.0, 60.0), (200.0, 60.0)]], n_boot=100)
    got = {(e["method"], e["baseline"]): e for e in out}
    assert set(got) == {("gmwm", "plain"), ("static_var", "plain"), ("gmwm", "static_var")}
    assert got[("gmwm", "plain")]["ratio"] == pytest.approx(0.5) and got[("gmwm", "plain")]["significant"]
    assert got[("static_var", "plain")]["ci"] == [1.0, 1.0] and got[("gmwm", "plain")]["n_independent"] == 3


def test_gain_share_is_the_log_ratio_of_the_geometric_means():
    rng = np.random.default_rng(4)
    ref = [_overlap_series(rng, 24, -0.35) for _ in range(6)]
    m = [0.5 * r + _overlap_series(rng, 24, 0.0, scale=0.05) for r in ref]
    m[2][5] = np.nan  # a window missing for the method is dropped from both sums
    out = gain_share(m, ref, 3, n_boot=500, seed=1)
    keep = [np.isfinite(g) for g in m]
    ra = bootstrap_ratio([g[k] for g, k in zip(m, keep)], 3, n_boot=50)["ratio"]
    rb = bootstrap_ratio([r[k] for r, k in zip(ref, keep)], 3, n_boot=50)["ratio"]
    assert out["share"] == pytest.approx(math.log(ra) / math.log(rb), rel=1e-12)
    assert out["n_windows"] == 6 * 24 - 1 and out["n_drives"] == 6
    assert out["ci"][0] < out["share"] < out["ci"][1]


def test_gain_share_ci_coverage():
    # the method's per-window log gain is half the reference's plus overlap-correlated noise and a drive
    # effect: the 95 % interval (drives resampled) holds the true share 0.5
    hits = 0
    for k in range(150):
        rng = np.random.default_rng(1000 + k)
        ref = [_overlap_series(rng, 24, -0.35) + rng.normal(0, 0.1) for _ in range(6)]
        m = [0.5 * r + _overlap_series(rng, 24, 0.0, scale=0.05) + rng.normal(0, 0.05) for r in ref]
        lo, hi = gain_share(m, ref, 3, n_boot=400, seed=k)["ci"]
        hits += lo < 0.5 < hi
    assert hits / 150 >= 0.86


def test_gain_share_exact_fraction_and_degenerate_cases():
    ref = [np.array([-0.4, -0.2, -0.3, -0.1]), np.array([-0.5, -0.3])]
    out = gain_share([0.25 * r for r in ref], ref, 2, n_boot=200)
    assert out["share"] == pytest.approx(0.25) and out["ci"] == pytest.approx([0.25, 0.25])
    assert gain_share([np.zeros(3)], [np.zeros(3)], 2)["share"] is None  # the reference gains nothing
    with pytest.raises(DataError, match="same windows"):
        gain_share([np.zeros(3)], [np.zeros(4)], 2)
