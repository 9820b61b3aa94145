"""The in-motion estimate's last steps (:mod:`imunoise.inuse.information`): Newton steps from the Hessian's own
runs land on a quadratic's minimum exactly, never raise the function, stay in the box and leave flat parameters
alone; in the estimate they finish a search stopped early, and the white factor's test is the profile
likelihood ratio (the wander searched again at factor 1), not the ratio with the wander kept."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

import imunoise.inuse.likelihood as lik_mod
from imunoise.inuse import estimate_in_motion
from imunoise.inuse.estimate import LR_WHITE
from imunoise.inuse.information import WIDE_SD, gradient, hessian, newton_finish
from imunoise.nav.defaults import default_axis_models

BOX = (np.full(3, -10.0), np.full(3, 10.0))
A = np.array([[4.0, 1.0, 0.5], [1.0, 3.0, -0.8], [0.5, -0.8, 2.0]])
XMIN = np.array([0.7, -1.2, 2.5])


A_INV_NORM = float(np.linalg.norm(np.linalg.inv(A), 2))


def _quadratic(x: np.ndarray) -> float:
    d = x - XMIN
    return float(0.5 * d @ A @ d + 3.0)


def _rounding(fun, p: np.ndarray, h: float) -> tuple[float, float]:
    """Bounds of the rounding in the central differences at ``p`` (exact in exact arithmetic on a quadratic): each
    value of ``fun`` within 10 ε |f| (a 3 × 3 quadratic form and its sums), F the largest |f| the differences
    evaluate; a second difference adds four values over h², a first difference two over 2h. Returns the bound
    for the Hessian's and for the gradient's entries."""
    grid = np.array(np.meshgrid(*[[-h, 0.0, h]] * p.size)).reshape(p.size, -1).T
    big = max(abs(fun(p + a)) for a in grid)
    err = 10.0 * np.finfo(float).eps * big
    return 4.0 * err / h**2, 2.0 * err / (2.0 * h)


def test_central_differences_are_exact_on_a_quadratic():
    x = np.array([0.1, 0.2, -0.3])
    tol_h, tol_g = _rounding(_quadratic, x, 0.25)
    assert np.allclose(hessian(_quadratic, x, 0.25), A, rtol=0, atol=tol_h)
    assert np.allclose(gradient(_quadratic, x, 0.25), A @ (x - XMIN), rtol=0, atol=tol_g)


def _step_tolerance(p0: np.ndarray) -> float:
    """How far one Newton step from ``p0`` can land from the minimum by rounding alone: ‖A⁻¹‖ (‖Δg‖ + ‖ΔH‖ ‖δ‖)
    with ‖Δg‖, ‖ΔH‖ from :func:`_rounding` (three entries per row)."""
    tol_h, tol_g = _rounding(_quadratic, p0, 0.25)
    return A_INV_NORM * 3.0 * (tol_g + tol_h * float(np.linalg.norm(XMIN - p0)))


def test_one_newton_step_lands_on_a_quadratics_minimum():
    fin = newton_finish(_quadratic, np.zeros(3), 0.25, *BOX)
    assert fin.steps == 1
    assert np.allclose(fin.p, XMIN, rtol=0, atol=_step_tolerance(np.zeros(3)))
    tol_h, tol_g = _rounding(_quadratic, fin.p, 0.25)
    # what is left is the gradient where the step landed: A (p − XMIN) within the step's rounding, plus its own
    g_max = float(np.linalg.norm(A, 2)) * _step_tolerance(np.zeros(3)) + math.sqrt(3.0) * tol_g
    assert fin.left <= 0.5 * A_INV_NORM * g_max**2
    # the inverse's perturbation: ‖ΔA⁻¹‖ ≤ ‖A⁻¹‖² ‖ΔA‖ / (1 − ‖A⁻¹‖ ‖ΔA‖)
    d_h = 3.0 * tol_h
    assert np.allclose(fin.cov, np.linalg.inv(A), rtol=0, atol=A_INV_NORM**2 * d_h / (1.0 - A_INV_NORM * d_h))


def test_a_decided_caller_gets_no_steps():
    """``decided(f, left)`` sees the value and the remaining decrease and ends the steps: a caller that asks whether
    the minimum is below a level stops when twice the remaining decrease cannot reach it."""
    seen = []

    def decided(f, left):
        seen.append((f, left))
        return f - 2.0 * left > -10.0  # 14.8 − 2·11.8 (the value and twice what is left of it above 3) > −10

    p0 = np.zeros(3)
    fin = newton_finish(_quadratic, p0, 0.25, *BOX, decided=decided)
    assert fin.steps == 0 and np.array_equal(fin.p, p0)
    # left = ½ gᵀ H⁻¹ g = f − 3 up to the rounding of g (×‖H⁻¹g‖) and of H (×‖δ‖² / 2)
    tol_h, tol_g = _rounding(_quadratic, p0, 0.25)
    step = float(np.linalg.norm(XMIN - p0))
    tol_left = 3.0 * (tol_g * step + 0.5 * tol_h * step**2)
    assert len(seen) == 1 and seen[0][0] == _quadratic(p0)
    assert seen[0][1] == pytest.approx(_quadratic(p0) - 3.0, rel=0, abs=tol_left)
    fin = newton_finish(_quadratic, p0, 0.25, *BOX, decided=lambda f, left: f - 2.0 * left > 2.5)
    assert fin.steps == 1 and np.allclose(fin.p, XMIN, rtol=0, atol=_step_tolerance(p0))


def test_the_steps_never_raise_the_function_and_stop_at_the_box():
    def fun(x):  # smooth, not quadratic, its minimum (3, …) outside the box's upper face x0 ≤ 1
        return float(np.sum(np.cosh(x - np.array([3.0, 0.0, 0.0]))))

    lo, hi = np.full(3, -1.0), np.array([1.0, 1.0, 1.0])
    p0 = np.array([-0.5, 0.4, -0.6])
    fin = newton_finish(fun, p0, 0.1, lo, hi, max_steps=10)
    assert fun(fin.p) < fun(p0)
    assert np.all(fin.p >= lo) and np.all(fin.p <= hi)
    assert fin.p[0] == 1.0  # pressed against the face the minimum lies beyond
    assert abs(fin.p[1]) < 1e-3 and abs(fin.p[2]) < 1e-3


def test_a_flat_parameter_is_not_moved():
    """A parameter whose curvature gives a 95 % interval wider than ×/÷ 10 is left out of the step (and of the
    covariance), however large its gradient."""
    flat = 0.5 / WIDE_SD**2  # below the curvature 1 / WIDE_SD² the covariance needs

    def fun(x):
        return float(2.0 * (x[0] - 1.0) ** 2 + 0.5 * flat * x[1] ** 2 + 5.0 * x[1])

    p0 = np.array([0.0, 0.3])
    fin = newton_finish(fun, p0, 0.25, np.full(2, -10.0), np.full(2, 10.0))
    assert fin.p[1] == 0.3 and math.isinf(fin.cov[1, 1])
    tol_h, tol_g = _rounding(fun, p0, 0.25)  # one step of length 1 on curvature 4: (Δg + ΔH·1) / 4
    assert abs(fin.p[0] - 1.0) <= (tol_g + tol_h) / 4.0


def _drive(n: int = 7200):
    return SimpleNamespace(imu=SimpleNamespace(t=np.arange(n, dtype=float)), init=SimpleNamespace(t=0.0),
                           gnss=SimpleNamespace(sigma_ned=np.ones((10, 3))), name="synthetic",
                           static_truth=np.arange(n) < 300)


K_STAR = 3e-5  # the gyro wander's driving density at the optimum [rad/s/√s]


def _gyro_valley(th: tuple, dip: float) -> float:
    """A gyro NLL in x = log f − 0.3, y = K/K* − 1, z = log τ − log 120 s: 100(x + y)² + 40y² + 20z², less a
    narrow dip of depth ``dip`` at f = 1 (x = −0.3, width 0.05: nothing of it reaches the optimum's curvature).
    The curvature at the optimum gives log f an sd of 0.13, so its Wald interval excludes f = 1. At f = 1 with
    the optimum's K kept, the ratio is 2(100·0.09 − dip); with K searched again (y = 0.3·100/140) it is
    2(0.09·100·40/140 − dip) = 2(2.57 − dip): the profile keeps f = 1 for dip = 1 (ratio 3.1) and rejects it
    without the dip (ratio 5.1). The valley x + y = const is 0.07 wide: the Hessian's step is 0.02."""
    white, sigma, tau = th
    v = 0.0
    for i in range(3):
        k = sigma[i] * math.sqrt(2.0 / tau[i])
        x = math.log(white[i]) - 0.3
        y = k / K_STAR - 1.0  # linear in K: the no-wander model (K = 0) is a finite y = −1
        z = math.log(tau[i]) - math.log(120.0)
        v += 100.0 * (x + y) ** 2 + 40.0 * y * y + 20.0 * z * z - dip * math.exp(-(((x + 0.3) / 0.05) ** 2))
    return v / 3.0


def _estimate(monkeypatch, nll, maxfev: int = 40, h: float = 0.02):
    monkeypatch.setattr(lik_mod, "in_motion_filter", lambda models, w, s, t: (tuple(w), tuple(s), tuple(t)))
    monkeypatch.setattr(lik_mod, "drive_terms", lambda drive, moving, th: np.array([nll(th)]))
    return estimate_in_motion([_drive()], default_axis_models(100.0), freq=100.0, groups=("gyro",), maxfev=maxfev,
                              h=h)


def test_the_white_factors_test_is_the_profile_likelihood_ratio(monkeypatch):
    est = _estimate(monkeypatch, lambda th: _gyro_valley(th, 1.0))
    lr = est.part.evidence["lr_white_one"]["gyro"]
    assert 0.0 <= lr < LR_WHITE < 2.0 * (_gyro_valley(((1.0,) * 3, (K_STAR * math.sqrt(60.0),) * 3, (120.0,) * 3),
                                                       1.0) - _gyro_valley(((math.exp(0.3),) * 3,
                                                                            (K_STAR * math.sqrt(60.0),) * 3,
                                                                            (120.0,) * 3), 1.0))
    ax = est.part.axis("gyro_x")
    assert ax.white_factor.value == 1.0 and ax.white_factor.ci95[0] <= 1.0 <= ax.white_factor.ci95[1]
    assert est.theta.white[:3] == (1.0, 1.0, 1.0)
    # the wander where the profile ended: K = (1 + 0.3·100/140) K* (the valley's floor at f = 1), not K*
    k = est.theta.sigma[0] * math.sqrt(2.0 / est.theta.tau_s[0])
    assert abs(k / K_STAR - (1.0 + 0.3 * 100.0 / 140.0)) < 0.01
    assert ax.bias.model == "gm" and ax.bias.ci95["sigma"][0] < ax.bias.sigma < ax.bias.ci95["sigma"][1]


def test_a_white_factor_the_profile_rejects_stays(monkeypatch):
    """The same valley without the dip: the profile ratio is 5.1 > 3.84, so the factor stays at e^0.3 with an
    interval that excludes 1."""
    est = _estimate(monkeypatch, lambda th: _gyro_valley(th, 0.0))
    assert est.part.evidence["lr_white_one"]["gyro"] > LR_WHITE
    wf = est.part.axis("gyro_x").white_factor
    assert abs(math.log(wf.value) - 0.3) < 0.02 and wf.ci95[0] > 1.0


def _error(th) -> float:
    """The largest distance of the gyro's log parameters from the valley's optimum (f = e^0.3, K = K*, τ = 120 s)."""
    k = th.sigma[0] * math.sqrt(2.0 / th.tau_s[0])
    return max(abs(math.log(th.white[0]) - 0.3), abs(k / K_STAR - 1.0), abs(math.log(th.tau_s[0] / 120.0)))


def test_newton_steps_finish_a_search_stopped_early(monkeypatch):
    """With 16 evaluations the simplex stops more than 0.05 from the valley's optimum in a log parameter (checked
    with the steps switched off); the Newton steps end within 0.02 of it in each (K relative to K*)."""
    import imunoise.inuse.estimate as est_mod

    est = _estimate(monkeypatch, lambda th: _gyro_valley(th, 0.0), maxfev=16)
    assert _error(est.theta) < 0.02
    real = est_mod.newton_finish
    monkeypatch.setattr(est_mod, "newton_finish", lambda *a, **k: real(*a, **{**k, "max_steps": 0}))
    assert _error(_estimate(monkeypatch, lambda th: _gyro_valley(th, 0.0), maxfev=16).theta) > 0.05
