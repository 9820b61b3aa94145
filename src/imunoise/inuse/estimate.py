"""The in-motion noise of an IMU from whole GNSS-aided drives: maximum likelihood of the GNSS innovations
(docs/guide/theory.rst, 'In-use noise'; the likelihood: :mod:`imunoise.inuse.likelihood`).

Per sensor group g (gyros, accelerometers) three parameters, log-parametrised: the white factor f_g (σ scale of
the static white density while moving) and the moving Gauss–Markov's driving density K_g = σ_g√(2/τ_g) and
correlation time τ_g (the GM evolves while moving and is frozen at stops; K rather than σ because a drive
shorter than τ sees the driving density, and σ, τ alone would lie on a ridge). The group's axes share them.
One group at a time, the other held at its current values (gyros first): the white factor without wander
(bounded golden search), then (log f, log K, log τ) by Nelder–Mead from the best of four starts (f = 1, the
static model, or the no-wander white factor; a moderate or a 30× smaller K). Where the wander's test
(below) passes at the search's end, Newton steps from the Hessian's own runs finish the search
(:mod:`imunoise.inuse.information`: the simplex stops short of the optimum by a sizeable part of a standard
deviation). Then:

* the wander's test: LR = 2(NLL(no wander, f searched again at the other group's final values) − NLL(θ̂))
  against χ²₂(0.95) = 5.99. Below it the wander is not given as a number: the bound says up to which σ (at
  τ = 60 s) the fixes still fit (ΔNLL ≤ 1.92) and why;
* the white factor's test: where its Wald interval (below) excludes 1, LR = 2(NLL(factor 1) − NLL(θ̂)) against
  χ²₁(0.95) = 3.84, the wander's K and τ searched again at factor 1 (the profile: kept as they were, the ratio
  overstates); below it the factor is 1, its interval the Wald one widened to 1 (the curvature at f̂ can exclude
  1 where the likelihood does not), the wander where the profile ended with its information there;
* intervals from the observed information: the Hessian of the NLL in the log parameters by central
  differences (step ``h``). A parameter whose curvature alone gives a 95 % interval wider than ×/÷ 10 is flat
  (not identified: a bound with the reason) and left out; the rest is inverted
  (:func:`~imunoise.inuse.information.covariance`); Wald intervals exp(θ̂ ± 1.96 sd), positive by construction;
  log σ = log K + ½ log τ − ½ log 2 takes its variance from both;
* the wander is reported as a GM (σ, τ) when both are identified and τ̂ is below its limit (three times the
  drives' moving time), as a random walk k = K when only K is (the data support a random walk), else as a
  bound;
* the model family's error: per group the dispersion c ≥ 1 of the fixes' scores against the information
  (:mod:`imunoise.inuse.dispersion`); the covariance is c times the information's inverse, and the wander's and
  the white factor's likelihood ratios and the bounds' levels are divided by c.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.optimize import minimize

from imunoise.errors import DataError
from imunoise.imu import AXES
from imunoise.inuse.information import WIDE_SD, covariance, dispersion_at, hessian, newton_finish
from imunoise.inuse.likelihood import DriveLikelihood, Theta
from imunoise.noise.in_motion import (
    AxisInMotion,
    BiasWander,
    Bound,
    InMotionPart,
    Interval,
    gm_equivalent_k,
    walk_tau_s,
)
from imunoise.noise.moved import renamed

__all__ = ["GROUPS", "InMotionEstimate", "estimate_in_motion", "static_models", "static_nk"]

GROUPS = {"gyro": (0, 1, 2), "accel": (3, 4, 5)}
SIGMA0 = {"gyro": 1e-4, "accel": 5e-3}  # start of σ [rad/s, m/s²]
SIGMA_RANGE = {"gyro": (1e-7, 1e-1), "accel": (1e-5, 1.0)}
WHITE_RANGE = (0.2, 50.0)
TAU_MIN_S = 2.0  # the longest τ searched is walk_tau_s (≥ 10 × this)
LR_WANDER = 5.991  # χ²₂(0.95)
LR_WHITE = 3.841  # χ²₁(0.95)
HALF_LR1 = 1.92  # ½ χ²₁(0.95)


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


def static_models(static_model: Any, freq: float) -> list:
    """The six static filter models (each with its rate) through the door: a model file /
    :class:`~imunoise.noise.imu_model.ImuModel` / parsed dict (:func:`imunoise.nav.defaults.load_axis_models`),
    or six filter models as they are."""
    from imunoise.nav.defaults import load_axis_models, normalize_axis_models

    if isinstance(static_model, list | tuple):
        return normalize_axis_models(list(static_model), freq)
    if hasattr(static_model, "to_dict"):
        static_model = static_model.to_dict()
    return load_axis_models(static_model, freq)


def static_nk(models: list, horizon_s: float) -> list[tuple[float, float]]:
    """Per axis the static (N [unit/√Hz], K [unit/√s]) of the six filter ``models``
    (:func:`imunoise.noise.equivalent_noise.equivalent_noise`, the mapping the exports use), slow AR1s matched
    over scales up to ``horizon_s`` [s]."""
    from imunoise.noise.equivalent_noise import equivalent_noise

    out = []
    for m in models:
        eq = equivalent_noise(m, m.freq, horizon_s=horizon_s)
        out.append((eq.N, eq.K))
    return out


# static_models was called static_pairs, though it returns models (each with its rate), not (model, rate) pairs
__getattr__ = renamed(__name__, {"static_pairs": (lambda: static_models, "imunoise.inuse.static_pairs is renamed "
                                  "static_models (it returns the six filter models, not pairs); the old name goes in "
                                  "the next release")})


def _factor_k(k_static: float, kw: float, kw_ci) -> Interval:
    """The in-use / static factor of K: √(K² + K_w²)/K with K_w the wander's driving density, its interval from
    K_w's (None when the static K is 0)."""
    if not k_static > 0:
        return Interval(None)
    val = math.hypot(k_static, kw) / k_static
    if kw_ci is None:
        return Interval(val, (val, val) if kw == 0 else None)
    return Interval(val, tuple(math.hypot(k_static, x) / k_static for x in kw_ci))


def _ci(x: float, sd: float) -> tuple[float, float] | None:
    """Wald interval of a positive parameter from the sd of its log."""
    return (x * math.exp(-1.96 * sd), x * math.exp(1.96 * sd)) if math.isfinite(sd) else None


def _unlog(p: np.ndarray) -> tuple[float, float, float]:
    """(f, σ, τ) of the search parameters (log f, log K, log τ), σ = K√(τ/2) (:func:`gm_equivalent_k`)."""
    f, k, tau = (float(x) for x in np.exp(p))
    return f, k * math.sqrt(tau / 2.0), tau


def _theta_with(th: Theta, idx: Sequence[int], f: float, s: float, tau: float) -> Theta:
    w, sg, ta = list(th.white), list(th.sigma), list(th.tau_s)
    for i in idx:
        w[i], sg[i], ta[i] = f, s, tau
    return replace(th, white=tuple(w), sigma=tuple(sg), tau_s=tuple(ta))


def _box(g: str, tau_max: float) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of (log f, log K, log τ) of group ``g``."""
    lo_s, hi_s = SIGMA_RANGE[g]
    lo = np.array([math.log(WHITE_RANGE[0]), math.log(gm_equivalent_k(lo_s, tau_max)), math.log(TAU_MIN_S)])
    hi = np.array([math.log(WHITE_RANGE[1]), math.log(gm_equivalent_k(hi_s, TAU_MIN_S)), math.log(tau_max)])
    return lo, hi


def _white_search(lik: DriveLikelihood, th: Theta, idx: Sequence[int], lo: float, hi: float, s: float, tau: float,
                  iters: int) -> float:
    """The group's log white factor in [lo, hi] at wander (σ, τ), bounded golden search."""
    from scipy.optimize import minimize_scalar

    r = minimize_scalar(lambda u: lik.nll(_theta_with(th, idx, math.exp(u), s, tau)), bounds=(lo, hi),
                        method="bounded", options={"xatol": 0.03, "maxiter": iters})
    return float(r.x)


def _search(lik: DriveLikelihood, th: Theta, g: str, tau_max: float, starts: Sequence[np.ndarray],
            maxfev: int) -> np.ndarray:
    """(log f, log K, log τ) of group ``g`` by Nelder–Mead from the best of ``starts``, the other groups held."""
    idx = GROUPS[g]
    lo, hi = _box(g, tau_max)

    def f(p: np.ndarray) -> float:
        c = np.clip(p, lo, hi)
        return lik.nll(_theta_with(th, idx, *_unlog(c))) + 10.0 * float(np.sum((p - c) ** 2))  # smooth wall

    x0 = min(starts, key=f)
    simplex = [x0, x0 + [0.5, 0, 0], x0 + [0, 1.5, 0], x0 + [0, 0, 1.2]]
    res = minimize(f, x0, method="Nelder-Mead", options={"initial_simplex": simplex, "xatol": 0.05, "fatol": 0.05,
                                                         "maxfev": maxfev})
    return np.clip(res.x, lo, hi)


def _starts(g: str, tau_max: float, us: Sequence[float]) -> list[np.ndarray]:
    """Starts of a group's search: each white factor of ``us`` with a moderate and a 30× smaller K. The wander
    model nests the no-wander one (K → 0), so a start near the no-wander optimum keeps the search from ending
    above the no-wander likelihood (a negative LR, measured on the real drive from f = 1 alone)."""
    tau0 = min(60.0, tau_max)
    k0 = math.log(gm_equivalent_k(SIGMA0[g], tau0))
    return [np.array([u, k, math.log(tau0)]) for u in us for k in (k0, k0 - math.log(30.0))]


def _no_wander(lik: DriveLikelihood, th: Theta, g: str, tau_max: float, near: float | None) -> tuple[float, float]:
    """The no-wander model of group ``g`` at the other groups' current values: its log white factor (bounded
    golden search, in the whole box or ±0.7 around ``near``) and its NLL."""
    idx = GROUPS[g]
    lo, hi = _box(g, tau_max)
    if near is None:
        u = _white_search(lik, th, idx, lo[0], hi[0], 0.0, 60.0, 14)
    else:
        u = _white_search(lik, th, idx, max(lo[0], near - 0.7), min(hi[0], near + 0.7), 0.0, 60.0, 8)
    return u, lik.nll(_theta_with(th, idx, math.exp(u), 0.0, 60.0))


def _held(th: Theta, g: str) -> tuple:
    """The parameters of the groups other than ``g`` in ``th`` (what group g's no-wander model is searched at)."""
    return tuple((th.white[i], th.sigma[i], th.tau_s[i]) for i in range(len(th.white)) if i not in GROUPS[g])


def _refine_no_wander(lik: DriveLikelihood, th: Theta, g: str, tau_max: float, u0: dict[str, float],
                      nll0: dict[str, float], refined: dict[str, tuple]) -> None:
    """Group ``g``'s no-wander model searched again near its last white factor ``u0[g]`` (:func:`_no_wander`) at
    the other groups' values in ``th``, into ``u0[g]``, ``nll0[g]``; skipped when that search was already made at
    these values (``refined``: per group the other groups' values of its last such search): the no-wander model
    of a group depends on the other groups alone, and the search again at unchanged values would only move
    its white factor within the search's tolerance. With two groups: the first group's search of the second
    pass, at the last group's final values, is the one its wander test uses; the last group's is made there."""
    held = _held(th, g)
    if refined.get(g) == held:
        return
    u0[g], nll0[g] = _no_wander(lik, th, g, tau_max, u0[g])
    refined[g] = held


def _white_profile(lik: DriveLikelihood, th: Theta, idx: Sequence[int], p: np.ndarray, H: np.ndarray, h: float,
                   box: tuple[np.ndarray, np.ndarray], level: float):
    """The wander model held at white factor 1: (log K, log τ) from the better of ``p``'s and the quadratic model's
    conditional optimum (``H`` the Hessian at ``p``), finished by Newton steps: their
    :class:`~imunoise.inuse.information.Information` and the NLL where they ended. The steps stop once twice the
    quadratic model's remaining decrease cannot bring the NLL below ``level`` (the test's decision is made)."""
    fun = lambda r: lik.nll(_theta_with(th, idx, *_unlog(np.array([0.0, *r]))))  # noqa: E731
    starts = [p[1:]]
    try:
        starts.append(np.clip(p[1:] + np.linalg.solve(H[1:, 1:], H[1:, 0] * p[0]), box[0][1:], box[1][1:]))
    except np.linalg.LinAlgError:
        pass
    fin = newton_finish(fun, min(starts, key=fun), h, box[0][1:], box[1][1:],
                        decided=lambda f, left: f - 2.0 * left > level)
    return fin, fun(fin.p)


def _sds(cov: np.ndarray) -> tuple[float, float, float, float]:
    """The sd of log f, log K, log τ (``cov``'s diagonal) and of log σ = log K + ½ log τ − ½ log 2 (from both)."""
    sd_f, sd_k, sd_t = (float(x) for x in np.sqrt(np.diag(cov)))
    var_s = cov[1, 1] + 0.25 * cov[2, 2] + cov[1, 2] if np.all(np.isfinite(cov[1:, 1:])) else math.inf
    return sd_f, sd_k, sd_t, (math.sqrt(var_s) if var_s >= 0 else math.inf)


def _scan_up(fun, x0: float, limit: float, level: float, step: float = 1.6) -> float | None:
    """The last x (×``step`` from ``x0``) with fun(x) ≤ ``level`` before it is exceeded, or None if not below
    ``limit``."""
    x, last = x0, None
    while x <= limit:
        if fun(x) > level:
            return last if last is not None else x
        last = x
        x *= step
    return None


def estimate_in_motion(drives: Sequence[Any], static_model: Any, *, freq: float, seed: int | None = None,
                       groups: Sequence[str] = ("gyro", "accel"), maxfev: int = 40, h: float = 0.25,
                       names: Sequence[str] | None = None, mapper: Any = None) -> InMotionEstimate:
    """Estimate the in-motion noise from whole GNSS-aided drives (module docstring).

    Parameters
    ----------
    drives : sequence
        Drives as the experiments' scenarios carry them (:mod:`imunoise.inuse.likelihood`); pooled.
    static_model : object
        The static part (the stops' model), mapped to the filter by the door: an
        :class:`~imunoise.noise.imu_model.ImuModel`, its parsed JSON, a model file's path, or the six
        filter models as they are.
    freq : float
        IMU rate [Hz] (the static model's parameters per sample at its own rate).
    seed : int, optional
        Unused by the deterministic search; accepted so every estimate takes a seed as the project's other
        random-capable paths do.
    groups : sequence of {"gyro", "accel"}
        The sensor groups to estimate (the others keep factor 1 and no wander).
    maxfev : int
        Likelihood evaluations per group in the Nelder–Mead search (a third of it in the second pass); Newton
        steps finish it, but cannot move a parameter the likelihood is flat in where the search left it: with 25
        the moving GM's τ stayed far out on simulated drives (docs/evidence/in_use_estimate.md, 'Where the
        search stops').
    h : float
        Step of the Hessian's differences in the log parameters.
    names : sequence of str, optional
        The drives' names for the evidence.
    mapper : DriveMapper, optional
        Where each evaluation's drive runs go (:class:`~imunoise.inuse.likelihood.DriveLikelihood`; on Dask:
        :func:`imunoise.inuse.fleet.fleet_mapper`); the estimate is the same.

    Returns
    -------
    InMotionEstimate
    """
    del seed
    t0 = time.process_time()
    lik = DriveLikelihood(list(drives), static_models(static_model, freq), mapper=mapper)
    tau_max = walk_tau_s(lik.hours_moving())  # a walk is reported at this bound and used in this form
    th = Theta()
    nll_static = lik.nll(th)
    if not math.isfinite(nll_static):
        raise DataError("the in-motion estimate: the GNSS-aided filter diverges on the drive(s) with the static "
                        "model alone; check the start (alignment at a stop), the lever arm and the GNSS file")
    logp: dict[str, np.ndarray] = {}
    nll0: dict[str, float] = {}
    u0: dict[str, float] = {}
    for g in groups:
        u0[g], nll0[g] = _no_wander(lik, th, g, tau_max, None)
        logp[g] = _search(lik, th, g, tau_max, _starts(g, tau_max, (0.0, u0[g])), maxfev)
        th = _theta_with(th, GROUPS[g], *_unlog(logp[g]))
    # the groups searched before the last one were searched with the later ones at their start values: search
    # them again at the others' final values, from where they ended or from the no-wander optimum there
    # (measured on the real drive: without it the gyros' wander model ended 10–40 NLL units above their
    # no-wander model once the accelerometers had been fitted)
    refined: dict[str, tuple] = {}
    for g in list(groups)[:-1]:
        _refine_no_wander(lik, th, g, tau_max, u0, nll0, refined)
        starts = [logp[g], np.array([u0[g], *logp[g][1:]]), *_starts(g, tau_max, (u0[g],))[1:]]
        logp[g] = _search(lik, th, g, tau_max, starts, maxfev // 3)
        th = _theta_with(th, GROUPS[g], *_unlog(logp[g]))
    # the search stops where its simplex is small, not at the optimum: Newton steps from the Hessian's own runs
    # finish it for every group whose wander the search already kept (imunoise.inuse.information)
    for g in groups:
        _refine_no_wander(lik, th, g, tau_max, u0, nll0, refined)
        if 2.0 * (nll0[g] - lik.nll(th)) > LR_WANDER:
            idx = GROUPS[g]
            fin = newton_finish(lambda p, idx=idx, th=th: lik.nll(_theta_with(th, idx, *_unlog(p))), logp[g], h,
                                *_box(g, tau_max))
            logp[g] = fin.p
            th = _theta_with(th, idx, *_unlog(fin.p))
    nk = static_nk(lik.models, max(float(d.imu.t[-1] - d.init.t) for d in lik.drives) / 2.0)
    axes: dict[str, AxisInMotion] = {}
    bounds: dict[str, Bound] = {}
    cov_log: dict[str, Any] = {}
    lrs: dict[str, float] = {}
    lr_white: dict[str, float] = {}
    dispersions: dict[str, float] = {}  # per group c ≥ 1 (imunoise.inuse.dispersion): intervals × √c, LRs ÷ c
    white_upper: dict[str, float | None] = {}  # the likelihood bound of a white factor that is not identified
    for g in groups:
        idx = GROUPS[g]
        nll_hat = lik.nll(th)
        # the LR compares two models that differ in this group's wander alone: the no-wander model at the other
        # groups' values as they are now
        _refine_no_wander(lik, th, g, tau_max, u0, nll0, refined)
        lr = 2.0 * (nll0[g] - nll_hat)
        lrs[g] = lr
        wander = lr > LR_WANDER
        c = 1.0
        if wander:  # the wander model's information and dispersion; its test is LR / c
            thf = lambda p, idx=idx, th=th: _theta_with(th, idx, *_unlog(p))  # noqa: E731
            H = hessian(lambda p, thf=thf: lik.nll(thf(p)), logp[g], h)
            cov = covariance(H)
            c = dispersion_at(lik, thf, logp[g], h, H, cov)
            wander = lr / c > LR_WANDER
        if not wander:  # the no-wander model: the white factor of the first search, σ = 0
            th = _theta_with(th, idx, math.exp(u0[g]), 0.0, 60.0)
            logp[g][0] = u0[g]
            nll_hat = lik.nll(th)
            thf = lambda p, idx=idx, th=th: _theta_with(th, idx, math.exp(p[0]), 0.0, 60.0)  # noqa: E731
            H = hessian(lambda p, thf=thf: lik.nll(thf(p)), logp[g][:1], h)
            c1 = covariance(H)
            c = dispersion_at(lik, thf, logp[g][:1], h, H, c1)
            cov = np.diag([c1[0, 0], math.inf, math.inf])
        cov = cov * c
        dispersions[g] = c
        cov_log[g] = cov.tolist()
        f, s, tau = _unlog(logp[g])
        k_hat = float(np.exp(logp[g][1]))
        sd_f, sd_k, sd_t, sd_s = _sds(cov)
        white = Interval(f, _ci(f, sd_f)) if sd_f <= WIDE_SD else Interval(None)
        if white.value is not None and white.ci95 is not None and not white.covers(1.0):
            # the Wald interval from the curvature at f̂ can exclude 1 where the likelihood does not (the NLL is not
            # quadratic in log f that far out; docs/evidence/in_use_ceiling.md, 'Under law none'): the factor
            # stays 1 unless the likelihood ratio rejects it, as the wander stays none unless its test does
            # (Wilks: with the wander's K and τ searched again at factor 1; kept as they were, the ratio overstates)
            r, nll1 = _white_profile(lik, th, idx, logp[g], H, h, _box(g, tau_max),
                                     nll_hat + 0.5 * LR_WHITE * c) if wander else (None, None)
            sw = s if wander else 0.0
            lr_white[g] = 2.0 * ((nll1 if r else lik.nll(_theta_with(th, idx, 1.0, sw, tau))) - nll_hat)
            if lr_white[g] / c < LR_WHITE:
                white = Interval(1.0, (min(white.ci95[0], 1.0), max(white.ci95[1], 1.0)))
                if r:  # the model held at factor 1: its wander where the profile ended, its information there
                    logp[g] = np.array([0.0, *r.p])
                    cov[1:, 1:] = r.cov * c
                    cov_log[g] = cov.tolist()
                    f, s, tau = _unlog(logp[g])
                    k_hat, sw = float(np.exp(logp[g][1])), s
                    _, sd_k, sd_t, sd_s = _sds(cov)
                f = 1.0
                th = _theta_with(th, idx, 1.0, sw, tau)
                logp[g][0] = 0.0
                nll_hat = lik.nll(th)
        up, reason, kw, kw_ci = None, "", 0.0, None
        if not wander:
            bias = BiasWander("none")
            up = _scan_up(lambda x, idx=idx, f=f, th=th: lik.nll(_theta_with(th, idx, f, x, 60.0)),
                          SIGMA_RANGE[g][0] * 100, SIGMA_RANGE[g][1], nll_hat + HALF_LR1 * c)
            by_c = f" / dispersion {c:.2f} = {lr / c:.2f}" if c > 1.0 else ""
            reason = (f"bias wander while moving not distinguishable from none: LR {lr:.2f}{by_c} < {LR_WANDER:.2f} "
                      "(χ²₂ 95 %); upper: σ at τ = 60 s")
        elif sd_t <= WIDE_SD and sd_s <= WIDE_SD and tau < 0.999 * tau_max:
            bias = BiasWander("gm", sigma=s, tau_s=tau, ci95={"sigma": _ci(s, sd_s), "tau_s": _ci(tau, sd_t)})
            kw, kw_ci = k_hat, _ci(k_hat, sd_k)
        elif sd_k <= WIDE_SD:  # τ not identified (or longer than the drives): the data support a random walk
            bias = BiasWander("rw", k=k_hat, ci95={"k": _ci(k_hat, sd_k)})
            kw, kw_ci = k_hat, _ci(k_hat, sd_k)
        else:
            bias = BiasWander("none")
            up = s * math.exp(1.96 * sd_s) if math.isfinite(sd_s) else None
            reason = (f"bias wander present (LR {lr:.1f}) but neither its σ, τ nor its driving density are "
                      "identified on these drives (95 % interval wider than ×/÷ 10)")
            if g == "accel":
                reason += "; accelerometer bias against attitude error needs turns and speed changes"
        if white.value is None:
            sw = s if wander else 0.0
            wu = _scan_up(lambda x, idx=idx, th=th, sw=sw, tau=tau: lik.nll(_theta_with(th, idx, x, sw, tau)), f,
                          WHITE_RANGE[1], nll_hat + HALF_LR1 * c, 1.5)
            white_upper[g] = wu
            text = "white factor not identified (95 % interval wider than ×/÷ 10)"
            if not reason:
                up = wu
            elif wu is not None:
                text += f", ≤ {wu:.3g}"
            reason = (reason + "; " if reason else "") + text
        for i in idx:
            a = AXES[i]
            axes[a] = AxisInMotion(white, bias, Interval(white.value, white.ci95), _factor_k(nk[i][1], kw, kw_ci))
            if reason:
                bounds[a] = Bound("bias" if bias.model == "none" else "white", up, reason)
    evidence = {"drives": list(names) if names is not None else [getattr(d, "name", f"drive {k}")
                                                                  for k, d in enumerate(lik.drives)],
                "hours_moving": lik.hours_moving(), "gnss_sigma_m": lik.gnss_sigma_m(),
                "method": "maximum likelihood of the GNSS innovations over the whole drives (prediction-error "
                          "decomposition), per sensor group; 95 % Wald intervals from the observed information "
                          "times the dispersion of the fixes' scores",
                "freq_hz": float(freq), "groups": list(groups), "nll": lik.nll(th), "nll_static": nll_static,
                "lr_wander": lrs, "lr_white_one": lr_white, "dispersion": dispersions,
                "white_upper": white_upper}
    part = InMotionPart(axes, bounds, evidence)
    return InMotionEstimate(part, th, lik.nll(th), nll_static, cov_log, lrs, lik.runs, time.process_time() - t0)
