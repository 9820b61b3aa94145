"""The one-cluster interval (imunoise.experiments.fixed_b): exact identities against hand computations, the
fixed-b critical values of Kiefer & Vogelsang, and how the calibrated critical value moves with ρ̃."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imunoise.errors import ModelError
from imunoise.experiments.fixed_b import (
    KV_B1_LIMIT,
    ar1_bias_corrected,
    ar1_critical,
    bartlett_lrv_b1,
    calibrated_critical,
    fixed_b_interval,
)
from imunoise.experiments.stats import bootstrap_ratio, paired_entry

SERIES = np.array([0.3, -0.1, 0.4, 0.2, 0.0, 0.5])


def test_bartlett_b1_by_hand_and_as_the_kernel_sum():
    # mean 0.2166…; demeaned partial sums S_t; ω̂² = 2/n² Σ S_t²
    x = SERIES
    e = x - x.mean()
    s = np.cumsum(e)
    want = 2.0 * float(np.sum(s ** 2)) / 36.0
    assert bartlett_lrv_b1(x) == pytest.approx(want, rel=1e-14)
    # hand: e = (1/12)(1, −3.8, 2.2, −0.2, −2.6, 3.4)·… written out: S = [.0833, −.2333, −.05, −.0667, −.2833, 0]
    assert s[-1] == pytest.approx(0.0, abs=1e-15)
    assert bartlett_lrv_b1(x) == pytest.approx(2.0 / 36.0 * (1 / 144 + 0.2333333 ** 2 + 0.05 ** 2 + 1 / 225
                                                               + 0.2833333 ** 2), rel=1e-6)
    # the same number as γ̂(0) + 2 Σ_{j<n} (1 − j/n) γ̂(j), the Bartlett kernel with bandwidth n
    n = x.size
    gam = [float(e[j:] @ e[:n - j]) / n for j in range(n)]
    kern = gam[0] + 2.0 * sum((1.0 - j / n) * gam[j] for j in range(1, n))
    assert bartlett_lrv_b1(x) == pytest.approx(kern, rel=1e-12)


def test_bias_corrected_lag1_autocorrelation():
    x = SERIES
    e = x - x.mean()
    rho = float(e[1:] @ e[:-1]) / float(e @ e)
    n = x.size
    want = min(max((rho + 1 / n) / (1 - 3 / n), 0.0), 0.98)
    assert ar1_bias_corrected(x) == pytest.approx(want, rel=1e-14)
    # solves ρ̂ = ρ̃ − (1 + 3ρ̃)/n where not clipped
    y = np.array([0.6, -0.5, -0.2, -0.3, -0.2, -0.2, -0.7, -0.5, -0.5, 0.7, 0.5, 0.1, 0.0, -0.2, -0.4, -0.3])
    r_t = ar1_bias_corrected(y)
    ey = y - y.mean()
    r_hat = float(ey[1:] @ ey[:-1]) / float(ey @ ey)
    assert 0.0 < r_t < 0.98 and r_hat == pytest.approx(r_t - (1 + 3 * r_t) / y.size, rel=1e-12)
    assert ar1_bias_corrected(np.array([1.0, 2.0, 3.0, 4.0])) == 0.98  # < 5 windows: assume the worst
    assert ar1_bias_corrected(np.array([1.0, -1.0] * 10)) == 0.0  # negative correlation: treated as white


def test_critical_values_reach_the_fixed_b_limit_of_kiefer_vogelsang():
    # KV (2002) Table 1, Bartlett b = 1: one-sided 97.5 % point 4.771 (two-sided 95 %), 95 %: 3.764 (two-sided 90 %)
    assert KV_B1_LIMIT == pytest.approx(4.771, abs=0.01)
    assert ar1_critical(400, 0.0, 0.95) == pytest.approx(4.771, abs=0.25)
    assert ar1_critical(400, 0.0, 0.90) == pytest.approx(3.764, abs=0.25)
    # strong dependence in short series: far above the limit; more so the closer ρ is to 1
    c = [ar1_critical(25, r) for r in (0.0, 0.5, 0.8, 0.9)]
    assert c == sorted(c) and c[2] > 7.0 and c[0] < 5.2


def test_calibrated_critical_value_is_deterministic_and_grows_with_rho():
    assert calibrated_critical(25, 0.3) == calibrated_critical(25, 0.3)
    cs = [calibrated_critical(25, r) for r in (0.0, 0.4, 0.8)]
    assert cs == sorted(cs)
    # averaging over ρ's uncertainty puts it above the plug-in AR(ρ̃) value where that value is steep
    assert calibrated_critical(25, 0.8) > ar1_critical(25, 0.8)
    with pytest.raises(ModelError, match="at least 2 windows"):
        calibrated_critical(1, 0.0)


def test_interval_is_the_hand_formula_and_the_one_drive_paired_entry_uses_it():
    x = np.array([0.12, 0.05, 0.20, 0.31, 0.18, 0.02, -0.04, 0.10, 0.15, 0.22, 0.09, 0.0])
    r = fixed_b_interval(x)
    se = math.sqrt(bartlett_lrv_b1(x) / x.size)
    c = calibrated_critical(x.size, ar1_bias_corrected(x))
    assert r["se"] == pytest.approx(se, rel=1e-14) and r["critical"] == pytest.approx(c, rel=1e-14)
    assert r["ci"] == pytest.approx([x.mean() - c * se, x.mean() + c * se], rel=1e-14)
    e = paired_entry("a", "b", "drift", {"a": [list(np.exp(x))], "b": [[1.0] * x.size]}, 3)
    assert e["scope"] == "one drive: the interval describes this drive's windows only"
    assert e["interval"] == "fixed-b t (AR(1)-calibrated)" and e["df"] is None and e["n_clusters"] == 1
    assert e["critical"] == pytest.approx(c, rel=1e-14)
    assert [math.log(v) for v in e["ci"]] == pytest.approx(r["ci"], rel=1e-10)
    # the result does not depend on the bootstrap arguments any more
    assert bootstrap_ratio([x], 3, seed=1, n_boot=100)["ci"] == bootstrap_ratio([x], 1, seed=9)["ci"]


def test_constant_one_drive_series_gives_the_point_interval():
    e = paired_entry("a", "b", "drift", {"a": [[2.0, 4.0, 6.0]], "b": [[1.0, 2.0, 3.0]]}, 3)
    assert e["ratio"] == pytest.approx(2.0) and e["ci"] == pytest.approx([2.0, 2.0]) and e["significant"]
