"""The in-motion noise of an IMU from whole GNSS-aided drives: maximum likelihood of the GNSS innovations
(docs/guide/theory.rst, 'In-use noise'; the likelihood: :mod:`imunoise.inuse.likelihood`).

Per sensor group g (gyros, accelerometers) three parameters, log-parametrised: the white factor f_g (σ scale of
the static white density while moving), the moving Gauss–Markov σ_g and τ_g (evolving while moving, frozen at
stops). The group's axes share them: one group at a time is fitted by Nelder–Mead on (log f, log σ, log τ), the
other group held at its current values (gyros first, then accelerometers). Then:

* the wander's test: LR = 2(NLL(f̂, σ = 0) − NLL(f̂, σ̂, τ̂)) against χ²₂(0.95) = 5.99 (σ and τ enter together;
  τ is not defined at σ = 0, so the test is conservative). Below it the wander is not identified: its value is
  null and the bound says up to which σ (at τ̂) the fixes still fit (ΔNLL ≤ 1.92) and why;
* intervals from the observed information: the Hessian of the NLL in the log parameters by central
  differences (step ``h``), Wald intervals exp(θ̂ ± 1.96 sd) (positive by construction). A parameter whose sd
  exceeds ln 10 / 1.96 (a 95 % interval wider than ×/÷ 10) is not identified: a bound with the reason;
* τ̂ at its upper limit (longer than the drives' moving time): the wander is reported as a random walk
  k = σ√(2/τ) (what the data support), its interval from σ's.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.optimize import minimize

from imunoise.imu import AXES
from imunoise.inuse.likelihood import DriveLikelihood, Theta
from imunoise.noise.in_motion import AxisInMotion, BiasWander, Bound, InMotionPart, Interval, gm_equivalent_k

__all__ = ["GROUPS", "InMotionEstimate", "estimate_in_motion", "static_nk", "static_pairs"]

GROUPS = {"gyro": (0, 1, 2), "accel": (3, 4, 5)}
SIGMA0 = {"gyro": 1e-4, "accel": 5e-3}  # start of σ [rad/s, m/s²]
SIGMA_RANGE = {"gyro": (1e-7, 1e-1), "accel": (1e-5, 1.0)}
WHITE_RANGE = (0.2, 50.0)
TAU_MIN_S = 2.0
LR_WANDER = 5.991  # χ²₂(0.95)
HALF_LR1 = 1.92  # ½ χ²₁(0.95)
WIDE_SD = math.log(10.0) / 1.96


@dataclass
class InMotionEstimate:
    """The estimate: the model file's ``part``, the pooled NLL at the optimum and with no in-motion noise
    (``nll_static``), the optimum per group (``theta``), the covariance of the log parameters per group, and
    the cost (filter runs, CPU seconds)."""

    part: InMotionPart
    theta: Theta
    nll: float
    nll_static: float
    cov_log: dict[str, Any] = field(default_factory=dict)
    lr_wander: dict[str, float] = field(default_factory=dict)
    runs: int = 0
    cpu_s: float = 0.0


def static_pairs(static_model: Any, freq: float) -> list:
    """The six static filter pairs through the door: a model file / :class:`~imunoise.noise.imu_model.ImuModel` /
    parsed dict (:func:`imunoise.nav.defaults.load_axis_models`), or six (model, freq) pairs as they are."""
    from imunoise.nav.defaults import load_axis_models

    if isinstance(static_model, list | tuple):
        return list(static_model)
    if hasattr(static_model, "to_dict"):
        static_model = static_model.to_dict()
    return load_axis_models(static_model, freq)


def static_nk(pairs: list, horizon_s: float) -> list[tuple[float, float]]:
    """Per axis the static (N [unit/√Hz], K [unit/√s]) of the filter pairs
    (:func:`imunoise.noise.equivalent_noise.equivalent_noise`, the mapping the exports use), slow AR1s matched
    over scales up to ``horizon_s`` [s]."""
    from imunoise.noise.equivalent_noise import equivalent_noise

    out = []
    for m, f in pairs:
        eq = equivalent_noise(m, f, horizon_s=horizon_s)
        out.append((eq.N, eq.K))
    return out


def _factor_k(k_static: float, bias: BiasWander, ci_sigma, tau: float) -> Interval:
    """The in-use / static factor of K: √(K² + K_w²)/K, its interval from σ's at τ̂ (None when K = 0)."""
    kw = bias.equivalent_k()
    if not k_static > 0 or bias.model == "none":
        return Interval(1.0 if k_static > 0 and bias.model == "none" else None)
    val = math.hypot(k_static, kw) / k_static
    if ci_sigma is None:
        return Interval(val)
    lo, hi = (math.hypot(k_static, gm_equivalent_k(x, tau)) / k_static for x in ci_sigma)
    return Interval(val, (lo, hi))


def _theta_with(th: Theta, idx: Sequence[int], f: float, s: float, tau: float) -> Theta:
    w, sg, ta = list(th.white), list(th.sigma), list(th.tau_s)
    for i in idx:
        w[i], sg[i], ta[i] = f, s, tau
    return replace(th, white=tuple(w), sigma=tuple(sg), tau_s=tuple(ta))


def _fit_group(lik: DriveLikelihood, th: Theta, g: str, tau_max: float, maxfev: int) -> tuple[Theta, np.ndarray]:
    idx = GROUPS[g]
    lo_s, hi_s = SIGMA_RANGE[g]
    lo = np.array([math.log(WHITE_RANGE[0]), math.log(lo_s), math.log(TAU_MIN_S)])
    hi = np.array([math.log(WHITE_RANGE[1]), math.log(hi_s), math.log(tau_max)])

    def f(p: np.ndarray) -> float:
        q = np.clip(p, lo, hi)
        pen = 10.0 * float(np.sum((p - q) ** 2))  # a smooth wall: Nelder–Mead stays inside the box
        return lik.nll(_theta_with(th, idx, *np.exp(q))) + pen

    x0 = np.array([0.0, math.log(SIGMA0[g]), math.log(min(60.0, tau_max))])
    simplex = np.array([x0, x0 + [0.5, 0, 0], x0 + [0, 1.5, 0], x0 + [0, 0, 1.2]])
    res = minimize(f, x0, method="Nelder-Mead",
                   options={"initial_simplex": simplex, "xatol": 0.05, "fatol": 0.05, "maxfev": maxfev})
    p = np.clip(res.x, lo, hi)
    return _theta_with(th, idx, *np.exp(p)), p


def _hessian(fun, p: np.ndarray, h: float) -> np.ndarray:
    n = p.size
    f0 = fun(p)
    H = np.zeros((n, n))
    e = np.eye(n) * h
    for i in range(n):
        H[i, i] = (fun(p + e[i]) - 2 * f0 + fun(p - e[i])) / (h * h)
        for j in range(i):
            H[i, j] = H[j, i] = (fun(p + e[i] + e[j]) - fun(p + e[i] - e[j]) - fun(p - e[i] + e[j])
                                 + fun(p - e[i] - e[j])) / (4 * h * h)
    return H


def _wald(H: np.ndarray) -> np.ndarray | None:
    """Covariance H⁻¹ when H is positive definite, else None."""
    try:
        np.linalg.cholesky(H)
    except np.linalg.LinAlgError:
        return None
    return np.linalg.inv(H)


def _white_only(lik: DriveLikelihood, th: Theta, idx: Sequence[int], h: float = 0.25) -> tuple[float, float | None]:
    """The group's white factor with no wander (bounded 1-D search in log f) and the variance of log f from
    the NLL's second difference (None when not positive)."""
    from scipy.optimize import minimize_scalar

    def fun(u: float) -> float:
        return lik.nll(_theta_with(th, idx, math.exp(u), 0.0, 60.0))

    r = minimize_scalar(fun, bounds=(math.log(WHITE_RANGE[0]), math.log(WHITE_RANGE[1])), method="bounded",
                        options={"xatol": 0.03, "maxiter": 14})
    u = float(r.x)
    d2 = (fun(u + h) - 2 * fun(u) + fun(u - h)) / (h * h)
    return math.exp(u), (1.0 / d2 if d2 > 0 else None)


def _sigma_upper(lik: DriveLikelihood, th: Theta, g: str, f: float, tau: float, nll_min: float) -> float | None:
    """Largest σ (×1.6 steps from the group's lower edge, at f and τ) with NLL ≤ min + 1.92, or None if never
    exceeded below the range's top."""
    s, hi = SIGMA_RANGE[g][0] * 10, SIGMA_RANGE[g][1]
    last = None
    while s <= hi:
        if lik.nll(_theta_with(th, GROUPS[g], f, s, tau)) > nll_min + HALF_LR1:
            return last if last is not None else s
        last = s
        s *= 1.6 if last > SIGMA0[g] / 10 else 10.0
    return None


def estimate_in_motion(drives: Sequence[Any], static_model: Any, *, freq: float, seed: int | None = None,
                       groups: Sequence[str] = ("gyro", "accel"), maxfev: int = 36, h: float = 0.25,
                       names: Sequence[str] | None = None) -> InMotionEstimate:
    """Estimate the in-motion noise from whole GNSS-aided drives (module docstring).

    Parameters
    ----------
    drives : sequence
        Drives as the experiments' scenarios carry them (:mod:`imunoise.inuse.likelihood`); pooled.
    static_model : ImuModel, dict, path or list of (Model, freq)
        The static part (the stops' model), mapped to the filter by the door.
    freq : float
        IMU rate [Hz] (the static model's parameters per sample at its own rate).
    seed : int, optional
        Unused by the deterministic search; accepted so every estimate takes a seed as the project's other
        random-capable paths do.
    groups : sequence of {"gyro", "accel"}
        The sensor groups to estimate (the others keep factor 1 and no wander).
    maxfev : int
        Likelihood evaluations per group in the search.
    h : float
        Step of the Hessian's differences in the log parameters.
    names : sequence of str, optional
        The drives' names for the evidence.

    Returns
    -------
    InMotionEstimate
    """
    del seed
    t0 = time.process_time()
    lik = DriveLikelihood(list(drives), static_pairs(static_model, freq))
    tau_max = max(3600.0 * lik.hours_moving() * 3.0, 10.0 * TAU_MIN_S)
    th = Theta()
    nll_static = lik.nll(th)
    logp: dict[str, np.ndarray] = {}
    for g in groups:
        th, logp[g] = _fit_group(lik, th, g, tau_max, maxfev)
    nll_hat = lik.nll(th)
    nk = static_nk(lik.pairs, max(float(d.imu.t[-1] - d.init.t) for d in lik.drives) / 2.0)
    axes: dict[str, AxisInMotion] = {}
    bounds: dict[str, Bound] = {}
    cov_log: dict[str, Any] = {}
    lrs: dict[str, float] = {}
    for g in groups:
        idx = GROUPS[g]
        f, s, tau = (float(x) for x in np.exp(logp[g]))
        lr = 2.0 * (lik.nll(_theta_with(th, idx, f, 0.0, tau)) - nll_hat)
        lrs[g] = lr
        wander = lr > LR_WANDER
        if wander:
            fun = lambda p, idx=idx, th=th: lik.nll(_theta_with(th, idx, *np.exp(p)))  # noqa: E731
            cov = _wald(_hessian(fun, logp[g], h))
        else:  # no wander: the white factor alone, refitted with σ = 0
            f, c1 = _white_only(lik, th, idx)
            th = _theta_with(th, idx, f, 0.0, tau)
            logp[g] = np.array([math.log(f), math.log(SIGMA_RANGE[g][0]), math.log(tau)])
            cov = None if c1 is None else np.diag([c1, math.inf, math.inf])
            nll_hat = lik.nll(th)
        cov_log[g] = None if cov is None else cov.tolist()
        sd = np.sqrt(np.diag(cov)) if cov is not None else np.full(3, math.inf)
        ci = [(math.exp(logp[g][i] - 1.96 * sd[i]), math.exp(logp[g][i] + 1.96 * sd[i])) if math.isfinite(sd[i])
              else None for i in range(3)]
        white = Interval(f if ci[0] is not None and sd[0] <= WIDE_SD else None,
                         ci[0] if ci[0] is not None and sd[0] <= WIDE_SD else None)
        if not wander:
            up = _sigma_upper(lik, th, g, f, tau, nll_hat)
            bias = BiasWander("none")
            reason = (f"bias wander while moving not distinguishable from none: LR {lr:.2f} < {LR_WANDER:.2f} "
                      "(χ²₂ 95 %)")
        elif sd[1] > WIDE_SD or sd[2] > WIDE_SD:
            up = ci[1][1] if ci[1] is not None else None
            bias = BiasWander("none")
            reason = (f"bias wander present (LR {lr:.1f}) but σ and τ not separable on these drives "
                      f"(95 % interval of σ or τ wider than ×/÷ 10)")
            if g == "accel":
                reason += "; accelerometer bias against attitude error needs turns and speed changes"
        elif tau >= tau_max * 0.999:
            k = gm_equivalent_k(s, tau)
            bias = BiasWander("rw", k=k, ci95={"k": (gm_equivalent_k(ci[1][0], tau), gm_equivalent_k(ci[1][1], tau))})
            up, reason = None, ""
        else:
            bias = BiasWander("gm", sigma=s, tau_s=tau, ci95={"sigma": ci[1], "tau_s": ci[2]})
            up, reason = None, ""
        for i in idx:
            a = AXES[i]
            fk = _factor_k(nk[i][1], bias, ci[1], tau) if wander else Interval(1.0 if nk[i][1] > 0 else None)
            axes[a] = AxisInMotion(white, bias, Interval(white.value, white.ci95), fk)
            if reason:
                bounds[a] = Bound("bias", up, reason)
            elif white.value is None:
                bounds[a] = Bound("white", ci[0][1] if ci[0] else None, "white factor not identified (flat likelihood)")
    evidence = {"drives": list(names) if names is not None else [getattr(d, "name", f"drive {k}")
                                                                  for k, d in enumerate(lik.drives)],
                "hours_moving": lik.hours_moving(), "gnss_sigma_m": lik.gnss_sigma_m(),
                "method": "maximum likelihood of the GNSS innovations over the whole drives (prediction-error "
                          "decomposition), per sensor group; 95 % Wald intervals from the observed information",
                "freq_hz": float(freq), "groups": list(groups), "nll": nll_hat, "nll_static": nll_static,
                "lr_wander": lrs}
    part = InMotionPart(axes, bounds, evidence)
    return InMotionEstimate(part, th, nll_hat, nll_static, cov_log, lrs, lik.runs, time.process_time() - t0)
