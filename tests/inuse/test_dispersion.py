"""The dispersion of the in-motion estimate (:mod:`imunoise.inuse.dispersion`): the robust score variance against
known long-run variances, the dispersion's identities, and the estimate's intervals and tests widened by it on a
likelihood whose fixes are correlated in time where the model says they are not."""

from __future__ import annotations

import math

import numpy as np
import pytest

import imunoise.inuse.likelihood as lik_mod
from imunoise.inuse import estimate_in_motion, summary_lines
from imunoise.inuse.dispersion import bandwidth, dispersion, hac, score_variance
from imunoise.nav.defaults import default_axis_models


def _ar1(phi: float, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    e = rng.standard_normal(n) * math.sqrt(1.0 - phi * phi)  # unit stationary variance
    x = np.empty(n)
    x[0] = rng.standard_normal()
    for k in range(1, n):
        x[k] = phi * x[k - 1] + e[k]
    return x


def test_hac_at_lag_0_is_the_centred_outer_product_and_adds_bartlett_weighted_lags():
    s = np.random.default_rng(1).standard_normal((50, 2))
    c = s - s.mean(axis=0)
    assert np.allclose(hac(s, 0), c.T @ c, rtol=0, atol=1e-12)
    lag1 = c[1:].T @ c[:-1]
    assert np.allclose(hac(s, 1), c.T @ c + 0.5 * (lag1 + lag1.T), rtol=0, atol=1e-12)


def test_the_score_variance_of_correlated_scores_is_their_long_run_variance():
    """AR(1) scores, φ = 0.8, unit variance: the variance of their sum is T(1 + φ)/(1 − φ) = 9T. Bartlett's
    estimate at the Newey–West lag (≈ 80 here) has a relative sd of √(4L/3T) ≈ 7 % and a bias of about −5 %:
    the tolerance is 25 %. White scores: T."""
    n = 20_000
    x = _ar1(0.8, n, 2)
    assert bandwidth(x) > bandwidth(_ar1(0.0, n, 3))
    assert score_variance([x[:, None]])[0, 0] / n == pytest.approx(9.0, rel=0.25)
    assert score_variance([_ar1(0.0, n, 4)[:, None]])[0, 0] / n == pytest.approx(1.0, rel=0.1)
    # drives are independent: their J add
    two = score_variance([x[: n // 2, None], x[n // 2:, None]])
    assert two[0, 0] == pytest.approx(score_variance([x[: n // 2, None]])[0, 0]
                                      + score_variance([x[n // 2:, None]])[0, 0], rel=1e-12)


def test_the_dispersion_is_the_mean_ratio_of_robust_to_model_variance_never_below_1():
    H = np.array([[4.0, 1.0], [1.0, 9.0]])
    assert dispersion(H, 2.0 * H) == pytest.approx(2.0, rel=1e-12)
    assert dispersion(H, 0.5 * H) == 1.0  # the information's intervals are a floor
    assert dispersion(np.array([[1.0, 2.0], [2.0, 1.0]]), H) == 1.0  # not positive definite: no dispersion
    assert dispersion(H, np.full((2, 2), np.nan)) == 1.0


def _estimate(monkeypatch, x: np.ndarray, v: float):
    """The gyro group's estimate on a likelihood of one drive whose fixes are ℓ_k(f) = ½(x_k²/(f²v) + log f²v):
    the white factor f of gyro x alone matters (no wander, so the no-wander path)."""
    from types import SimpleNamespace

    def drive_terms(drive, moving, th):
        w2 = th[0][0] ** 2 * v
        return 0.5 * (x * x / w2 + math.log(w2))

    monkeypatch.setattr(lik_mod, "in_motion_filter", lambda models, w, s, t: (tuple(w), tuple(s), tuple(t)))
    monkeypatch.setattr(lik_mod, "drive_terms", drive_terms)
    n = x.size
    drive = SimpleNamespace(imu=SimpleNamespace(t=np.arange(n, dtype=float)), init=SimpleNamespace(t=0.0),
                            gnss=SimpleNamespace(sigma_ned=np.ones((10, 3))), name="synthetic",
                            static_truth=np.arange(n) < 10)
    return estimate_in_motion([drive], default_axis_models(100.0), freq=100.0, groups=("gyro",))


@pytest.mark.parametrize("phi", [0.0, 0.7])
def test_intervals_widen_by_the_dispersion_of_time_correlated_fixes(monkeypatch, phi):
    """Fixes whose squared innovations are correlated (AR(1) x, φ = 0.7) where the model treats them as independent:
    the information identity fails by (1 + φ²)/(1 − φ²) = 2.92 (the long-run variance of x² over its variance),
    times the central differences' own factor at step h = 0.25 (the scores' secant sinh(2h)/2h squared over the
    second difference's 2(cosh 2h − 1)/(2h)²). The sample is scaled so that the white factor's estimate is e^0.03
    exactly (√ of the mean of x²/v): with independent fixes (φ = 0, c = 1; sd of log f 1/√(2T) = 0.011) its
    interval excludes 1; with the correlated ones it is √c wider and contains 1. Relative sd of the estimated c
    over 4000 fixes ≈ 10 %."""
    h = 0.25
    v = 4e-8
    x = _ar1(phi, 4000, 5)
    x *= math.sqrt(math.exp(0.06) * v / np.mean(x * x))
    est = _estimate(monkeypatch, x, v)
    c = est.part.evidence["dispersion"]["gyro"]
    fd = (math.sinh(2 * h) / (2 * h)) ** 2 / (2 * (math.cosh(2 * h) - 1) / (2 * h) ** 2)
    assert c == pytest.approx(max(1.0, (1 + phi**2) / (1 - phi**2) * fd), rel=0.3)
    wf = est.part.axes["gyro_x"].white_factor
    assert math.log(wf.value) == pytest.approx(0.03, abs=0.003)  # the golden search's tolerance, as it converges
    lo, hi = wf.ci95
    # the interval is the information's, √c wider: its log half-width is 1.96 sd with sd² = c / H
    u = math.log(wf.value)
    H = float(np.sum(0.5 * x * x / v * (np.exp(-2 * (u + h)) - 2 * np.exp(-2 * u) + np.exp(-2 * (u - h))))) / h**2
    assert math.log(hi / lo) / (2 * 1.96) == pytest.approx(math.sqrt(c / H), rel=1e-3)
    assert wf.covers(1.0) == (phi > 0)
    # the summary says so where it widened the intervals
    assert any("dispersion" in line for line in summary_lines(est.part)) == (c > 1.0)


def test_the_likelihood_keeps_each_fix_term_and_its_nll_is_their_sum(monkeypatch):
    """The per-fix terms the scores come from are those of the NLL's own runs: the cached NLL is their NaN-skipping
    sum to the bit, one run per drive and θ (a fix without a term, NaN, adds nothing)."""
    from types import SimpleNamespace

    from imunoise.inuse.likelihood import DriveLikelihood, Theta

    calls = []

    def drive_terms(drive, moving, th):
        calls.append(th)
        return np.array([0.1, np.nan, 0.25 * th[0][0], drive.k])

    monkeypatch.setattr(lik_mod, "in_motion_filter", lambda models, w, s, t: (tuple(w), tuple(s), tuple(t)))
    monkeypatch.setattr(lik_mod, "drive_terms", drive_terms)
    drives = [SimpleNamespace(k=k, static_truth=np.zeros(4, dtype=bool)) for k in (1.0, 2.0)]
    lik = DriveLikelihood(drives, default_axis_models(100.0))
    th = Theta(white=(2.0,) * 6)
    total = lik.nll(th)
    terms = lik.terms(th)
    assert len(calls) == 2 and lik.runs == 2  # terms() reused the runs of nll()
    assert total == float(np.nansum(terms[0])) + float(np.nansum(terms[1])) == 0.1 + 0.5 + 1.0 + 0.1 + 0.5 + 2.0
