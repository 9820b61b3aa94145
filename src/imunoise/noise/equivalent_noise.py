"""The one mapping from a fitted composite model to a white-noise + random-walk pair (N, K)
(docs/guide/theory.rst, 'Latent processes' and 'Interfaces').

Kalibr, OpenVINS and ORB-SLAM3 (and the white/RW part of the online filter) know two processes per axis:
white noise of density N and a bias random walk of density K. A fitted model has more (AR1 / Gauss–Markov,
QN, DR). This module maps the model to the pair **by what the filter will see**: the (N, K) whose Allan
variance (Haar wavelet variance, AV = 2ν², docs/guide/theory.rst, 'Conventions') best matches the model's over the
scales that matter, from the update period Δt = 1/f (Haar level 1, τ = 2 samples) to a horizon T_h (default: the longest
scale of the data the model was fitted on, :func:`default_horizon_s`).

Rule, per axis (parameters per sample at f, docs/guide/theory.rst, 'Latent processes'):

1. Closed forms (no matching needed): WN → white σ² (N = σ·√Δt); RW → γ² (K = γ/√Δt); QN → white with
   its per-sample variance 2Q² (``qn="white"``, as :meth:`imunoise.noise.model.Model.white_variance`) or dropped
   (``qn="drop"``); an AR1 that decorrelates within ``white_below_s`` (default: one update period) → white
   with its exact zero-frequency density σ²/(1−φ)² per sample, since a filter cannot resolve a correlation
   shorter than its step (for T_c ≫ Δt that density is σ_GM·√(2T_c); at T_c = Δt/2 the sampled AR1's is
   √((1+φ)/(1−φ)·Δt/(2T_c)) = 1.15 times that limit, and the sampled one is what the integrated samples
   and the data's Allan curve show); DR → the random walk with the same AV at the horizon
   (:func:`dr_equivalent_rw`: on the scales of a static record a ramp and a random walk are two readings
   of one rising AV, and a ramp has no slot).
2. Every other AR1 is matched: the target is the model's AV (the exact parts as in 1); (N², K²) minimise
   Σ_T [ln AV_pair(T) − ln AV_target(T)]² over a log grid of averaging times T ∈ [Δt, T_h]
   (``POINTS_PER_OCTAVE`` per octave, whole numbers of samples), N² and K² not below their exact parts.
   A Gauss–Markov term of correlation time T_c is white noise on scales ≫ T_c (density σ_GM·√(2T_c)) and a
   random walk of its innovation on scales ≪ T_c (K² = 2σ²_GM/T_c): an AR1 with T_c ≫ T_h goes to K, one
   with T_c ≪ T_h mostly to N, and one whose bump (the "bias instability") lies inside the range is neither —
   the pair cannot follow it, and the worst AV ratio says by how much.
   Both lines stay at or below the target, as in an IEEE Allan reading (a noise line is never drawn above
   the curve it is read from): K² ≤ min_T 3·AV(T)/T over the whole range — K never claims more bias wander
   than the model shows at any scale, so a bias-instability bump cannot leak into K (nor the AV minimum);
   N² ≤ min T·AV(T) over the scales where the target falls like white noise (local slope ≤ −0.7, see
   :func:`white_region`) — not at scales shorter than a Gauss–Markov term's T_c, where the term is smooth
   and far below its white asymptote (that would drop the white part of every T_c slightly above Δt).
   Without the caps the least squares fills a bias-instability bump with K (K above the data's Allan
   bound on 30 of 30 ADIS16405 axes) or, K capped alone, with N (N up to 1.9 x the Allan reading).
3. Diagnostics: the τ range, the worst factor between the pair's AV and the target's over the grid (and
   whether the pair is above or below there), and per process where it went (:class:`Route`). Exports warn
   when the worst factor exceeds ``WARN_RATIO`` = 2.

4. The data's bound (``data_av``, exports only): the written K never exceeds what the data's own Allan
   variance supports, K_data = min_τ √(3·AVAR(τ)/τ) over the points an Allan reading uses (≥ 3 equivalent
   degrees of freedom, :func:`imunoise.noise.allan.rw_bound`). The pair above is bounded by the *model's* AV; a
   fitted RW term (exact, rule 1) can still overshoot the data's long-τ AV (up to 1.6x on ADIS16405 axes),
   and a file that hands a VIO stack more bias wander than the data ever showed is not a statement the data
   make. When the model's K exceeds K_data, K = K_data, and the Equivalent says so (``capped``,
   ``K_model``, ``K_data`` at ``K_data_at_s``). N is kept: it is read where the AV falls like white noise.
   The bound is the minimum of a noisy curve and so lies low: on simulated WN + RW (2^18 samples, 20 seeds)
   it is 0.57–1.21x the true K (mean 0.90), and a correct WN + RW fit is capped in about 4 of 10 records —
   the cap trades a K that may be low for never stating more bias wander than the data show.

The export (:mod:`imunoise.export`) and the filter mapping (:func:`imunoise.nav.filter_model.filter_model`)
both call :func:`equivalent_noise`; the online engine keeps AR1s with ``fold_tau_s`` ≤ T_c ≤ horizon as
Gauss–Markov states and passes the rest here with ``white_below_s = fold_tau_s``. The online mapping passes
no ``data_av``, so the filter keeps the model's own RW: rule 4 is for the exported pair, which states what
the data support, while the filter propagates the fitted model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.optimize import least_squares, nnls

from imunoise.errors import ModelError
from imunoise.noise.allan import AllanVariance, rw_bound
from imunoise.noise.model import Model
from imunoise.noise.processes import ar1_white_variance, dr_equivalent_rw

__all__ = [
    "POINTS_PER_OCTAVE",
    "WARN_RATIO",
    "Route",
    "Equivalent",
    "equivalent_noise",
    "pair_wv",
    "ar1_white_variance",
    "dr_equivalent_rw",
    "data_horizon",
    "default_horizon_s",
    "match_grid",
    "white_region",
]

POINTS_PER_OCTAVE = 8
WARN_RATIO = 2.0
WHITE_SLOPE = -0.7


def data_horizon(fit: Any) -> float | None:
    """The longest Haar scale τ_J (samples) of the WV a fit was made on (levels with too few coefficients are
    already dropped by :func:`imunoise.noise.wv.wavelet_variance`); None when the fit carries no WV."""
    wv = getattr(fit, "wv", None)
    return float(wv.scales[-1]) if wv is not None else None


def default_horizon_s(fit: Any) -> float | None:
    """The default matching horizon in seconds of averaging time: the longest Haar scale of the fit's data,
    τ_J samples ↔ averaging time T = τ_J/2 samples (AV(T) = 2ν²(τ = 2T·f), docs/guide/theory.rst, 'Conventions')."""
    tau = data_horizon(fit)
    return None if tau is None else tau / (2.0 * float(fit.freq))


def pair_wv(tau: np.ndarray, sigma2: float, gamma2: float) -> np.ndarray:
    """Haar WV of WN(σ²) + RW(γ²) at scales τ (samples; docs/guide/theory.rst, 'Latent processes' closed forms)."""
    tau = np.asarray(tau, dtype=float)
    return sigma2 / tau + gamma2 * (tau * tau + 2.0) / (12.0 * tau)


def match_grid(freq: float, horizon_s: float) -> np.ndarray:
    """Averaging times in samples m (integers, log grid from 1 to T_h·f); the Haar scales are τ = 2m."""
    m_h = float(horizon_s) * float(freq)
    if not m_h >= 1.0:
        raise ModelError(f"the matching horizon ({horizon_s:g} s) is shorter than one update period ({1 / freq:g} s)")
    n = max(2, int(math.ceil(math.log2(m_h) * POINTS_PER_OCTAVE)) + 1)
    return np.unique(np.round(np.geomspace(1.0, m_h, n)))


@dataclass(frozen=True)
class Route:
    """Where one process of the model went: ``slot`` "N", "K", "N+K" (matched) or "-" (dropped)."""

    process: str
    slot: str
    how: str


@dataclass(frozen=True)
class Equivalent:
    """The pair of one axis: per-sample ``sigma2`` (white) and ``gamma2`` (RW innovation) at ``freq``.

    ``*_exact``: the closed-form parts (rule 1); ``*_cap``: the largest line at or below the target's AV over
    the range (the tangent an IEEE Allan reading would draw; used when a slot is not identified; ``gamma2_cap``
    also at or below the data's bound when one was given);
    ``tau_range_s``: (Δt, T_h) averaging times matched on (None when nothing needed matching);
    ``worst_ratio`` ≥ 1 the worst factor between the pair's and the target's AV there, at ``worst_at_s``,
    ``worst_over`` True when the pair is above the model there. Rule 4: ``K_data`` the data's Allan bound on K
    (at averaging time ``K_data_at_s``; NaN when no data curve was given), ``K_model`` the model's K before
    it, ``capped`` whether K was lowered to ``K_data``.
    """

    freq: float
    sigma2: float
    gamma2: float
    sigma2_exact: float
    gamma2_exact: float
    sigma2_cap: float
    gamma2_cap: float
    tau_range_s: tuple[float, float] | None
    worst_ratio: float
    worst_at_s: float
    worst_over: bool
    matched: bool
    routes: tuple[Route, ...]
    m: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    target: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    K_data: float = math.nan
    K_data_at_s: float = math.nan
    K_model: float = math.nan
    capped: bool = False

    @property
    def N(self) -> float:
        """Continuous white-noise density [u/√Hz] = σ·√Δt."""
        return math.sqrt(self.sigma2 / self.freq)

    @property
    def K(self) -> float:
        """Continuous random-walk density [u/s/√Hz] = γ/√Δt."""
        return math.sqrt(self.gamma2 * self.freq)

    def mismatch(self, N: float, K: float) -> tuple[float, float, bool]:
        """(worst factor ≥ 1, at averaging time [s], pair above?) of another continuous pair (N, K) against
        this axis's target over the same grid — e.g. the pair written after combining three axes."""
        if self.m.size == 0:
            return 1.0, math.nan, False
        return _worst(pair_wv(2.0 * self.m, N * N * self.freq, K * K / self.freq), self.target, self.m, self.freq)

    def with_pair(self, sigma2: float, gamma2: float) -> Equivalent:
        """The same diagnostics for another per-sample pair (used when a rule replaces the matched one)."""
        if self.m.size:
            worst, at, over = _worst(pair_wv(2.0 * self.m, sigma2, gamma2), self.target, self.m, self.freq)
        else:
            worst, at, over = 1.0, math.nan, False
        return replace(self, sigma2=sigma2, gamma2=gamma2, worst_ratio=worst, worst_at_s=at, worst_over=over)

    def cap_text(self) -> str:
        """Rule 4 in words ("" when K was not capped)."""
        if not self.capped:
            return ""
        return (f"K capped at the data's Allan bound {self.K_data:.3g} at tau = {self.K_data_at_s:.4g} s "
                f"(min AD*sqrt(3/tau) over points with >= 3 dof); the fitted model gives {self.K_model:.3g}")

    def describe(self) -> str:
        """One line per process: which slot it went to and why."""
        return "; ".join(f"{r.process} -> {r.slot} ({r.how})" for r in self.routes)


def _worst(pair: np.ndarray, target: np.ndarray, m: np.ndarray, freq: float) -> tuple[float, float, bool]:
    lr = np.log(pair) - np.log(target)
    i = int(np.argmax(np.abs(lr)))
    return float(math.exp(abs(lr[i]))), float(m[i] / freq), bool(lr[i] > 0)


def equivalent_noise(
    model: Model,
    freq: float | None = None,
    *,
    horizon_s: float | None = None,
    white_below_s: float | None = None,
    qn: str = "white",
    data_av: AllanVariance | None = None,
) -> Equivalent:
    """The (N, K) pair of ``model`` (per sample at ``freq`` Hz) by the rule of the module docstring.

    Parameters
    ----------
    model
        A model with known parameters (per sample at its rate).
    freq
        Update (= sample) rate [Hz]; the matching starts at Δt = 1/freq. The model's own rate; given only for a
        model without one (a different one is refused: :meth:`~imunoise.noise.model.Model.sample_rate`).
    horizon_s
        Longest averaging time matched on [s] (default for fits: :func:`default_horizon_s`). Required when
        the model has a process that needs matching (an AR1 slower than ``white_below_s``, a DR).
    white_below_s
        AR1s with T_c ≤ this [s] are white by their exact zero-frequency density (default 1/freq).
    qn
        ``"white"`` (QN → white, 2Q² per sample) or ``"drop"``.
    data_av
        The data's Allan curve (:func:`imunoise.noise.allan.data_curve`): K is capped at its bound (rule 4).
        Exports pass it; the online filter mapping does not.

    Returns
    -------
    Equivalent
        The pair (per sample and continuous), its diagnostics and the route of every process.
    """
    freq = model.sample_rate(freq, "equivalent_noise")
    eq = _model_pair(model, freq, horizon_s=horizon_s, white_below_s=white_below_s, qn=qn)
    eq = replace(eq, K_model=eq.K)
    if data_av is None:
        return eq
    k_data, at = rw_bound(data_av)
    if not k_data > 0:
        return eq
    g2_data = k_data * k_data / eq.freq
    # the cap also bounds the fallback "half the largest RW under the AV" of an export (gamma2_cap)
    eq = replace(eq, K_data=k_data, K_data_at_s=at, gamma2_cap=min(eq.gamma2_cap, g2_data))
    if eq.gamma2 > g2_data:
        eq = replace(eq.with_pair(eq.sigma2, g2_data), capped=True)
    return eq


def _model_pair(model: Model, freq: float, *, horizon_s: float | None, white_below_s: float | None,
                qn: str) -> Equivalent:
    """Rules 1–3: the pair bounded by the model's own AV."""
    if not freq > 0:
        raise ModelError(f"sampling frequency must be > 0 Hz, got {freq}")
    if qn not in ("white", "drop"):
        raise ModelError(f"qn must be 'white' or 'drop', got {qn!r}")
    freq = float(freq)
    dt = 1.0 / freq
    white_below = dt if white_below_s is None else float(white_below_s)
    s2_exact = 0.0
    g2_exact = 0.0
    matched = []
    routes = []
    for name, c in zip(model.component_names(), model.components):
        part = c.equivalent_part(name, freq, white_below, horizon_s, qn, str(model))
        if part.matched:
            matched.append(c)
        else:
            if part.sigma2:
                s2_exact += part.sigma2
            if part.gamma2:
                g2_exact += part.gamma2
        routes.append(Route(name, part.symbol, part.text))
    if not matched:
        # only exact parts: the pair is the model's own (its AV equals the target at every scale)
        if horizon_s is None:
            return Equivalent(freq, s2_exact, g2_exact, s2_exact, g2_exact, s2_exact, g2_exact, None, 1.0,
                              dt, False, False, tuple(routes))
        m = match_grid(freq, horizon_s)
        tau = 2.0 * m
        target = pair_wv(tau, s2_exact, g2_exact)
        s2_cap, g2_cap = _caps(target, tau, s2_exact, g2_exact)
        return Equivalent(freq, s2_exact, g2_exact, s2_exact, g2_exact, s2_cap, g2_cap, (dt, float(m[-1]) / freq),
                          1.0, dt, False, False, tuple(routes), m, target)
    if horizon_s is None:
        raise ModelError(
            f"{model}: matching {', '.join(c.kind for c in matched)} to white noise + random walk needs a "
            "horizon (the longest averaging time that matters, s); give horizon_s / --horizon"
        )
    m = match_grid(freq, horizon_s)
    tau = 2.0 * m
    target = pair_wv(tau, s2_exact, g2_exact) + np.sum([c.wv(tau) for c in matched], axis=0)
    if not np.all(np.isfinite(target)) or not np.all(target > 0):
        raise ModelError(f"{model}: its Allan variance is not positive and finite over the range; cannot map it")
    w1 = 1.0 / tau
    w2 = (tau * tau + 2.0) / (12.0 * tau)
    s2_cap, g2_cap = _caps(target, tau, s2_exact, g2_exact)
    s2, g2 = _fit_pair(target, w1, w2, (s2_exact, s2_cap), (g2_exact, g2_cap))
    worst, at, over = _worst(pair_wv(tau, s2, g2), target, m, freq)
    return Equivalent(freq, s2, g2, s2_exact, g2_exact, s2_cap, g2_cap, (dt, float(m[-1]) / freq), worst, at,
                      over, True, tuple(routes), m, target)


def white_region(target: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Grid points where the target's AV falls at least like white noise's: local log-log slope ≤
    ``WHITE_SLOPE`` (white: −1; the Allan reading's tolerance ±0.15 on the AD slope −½ is ±0.3 here), the
    slope a least-squares line over ±1 octave (as :func:`imunoise.noise.allan.read_allan`)."""
    lt, ly = np.log(tau), np.log(target)
    slope = np.full(tau.size, np.nan)
    for i in range(tau.size):
        sel = np.abs(lt - lt[i]) <= math.log(2.0) + 1e-12
        if np.sum(sel) >= 2:
            x = lt[sel] - lt[sel].mean()
            slope[i] = float(x @ (ly[sel] - ly[sel].mean()) / (x @ x))
    return slope <= WHITE_SLOPE


def _caps(target: np.ndarray, tau: np.ndarray, s2_exact: float, g2_exact: float) -> tuple[float, float]:
    """Upper ends of the search (never below the exact parts, which are kept as they are): the largest RW γ²
    whose WV stays at or below ``target`` at every τ, and the largest white σ² at or below it wherever the
    target falls like white noise (everywhere when it never does)."""
    white = white_region(target, tau)
    sel = white if np.any(white) else np.ones(tau.size, dtype=bool)
    s2_cap = max(s2_exact, float(np.min((target * tau)[sel])))
    g2_cap = max(g2_exact, float(np.min(target * 12.0 * tau / (tau * tau + 2.0))))
    return s2_cap, g2_cap


def _fit_pair(y: np.ndarray, w1: np.ndarray, w2: np.ndarray, box_a: tuple[float, float],
              box_b: tuple[float, float]) -> tuple[float, float]:
    """argmin Σ (ln(a·w1 + b·w2) − ln y)² over a ∈ box_a, b ∈ box_b (both scaled by their upper ends)."""
    sa = box_a[1] if box_a[1] > 0 else 1.0
    sb = box_b[1] if box_b[1] > 0 else 1.0
    lo = np.array([box_a[0] / sa, box_b[0] / sb])
    hi = np.array([box_a[1] / sa, box_b[1] / sb])
    free = hi > lo * (1.0 + 1e-12) + 1e-300
    ly = np.log(y)
    cols = np.column_stack([sa * w1, sb * w2])

    def full(x: np.ndarray) -> np.ndarray:
        out = lo.copy()
        out[free] = x
        return out

    def res(x: np.ndarray) -> np.ndarray:
        return np.log(cols @ full(x)) - ly

    def jac(x: np.ndarray) -> np.ndarray:
        p = cols @ full(x)
        return (cols / p[:, None])[:, free]

    if not np.any(free):
        x = lo
    else:
        # start from the relative-error linear fit (NNLS on rows weighted by 1/y), then polish in log space
        x_lin, _ = nnls(cols / y[:, None], np.ones_like(y))
        starts = [np.clip(x_lin, lo, hi), hi.copy(), np.array([hi[0], lo[1]]), np.array([lo[0], hi[1]])]
        best = None
        for st in starts:
            x0 = st[free]
            x0 = np.minimum(np.maximum(x0, lo[free] + 1e-9 * (hi[free] - lo[free])), hi[free])
            if np.any(cols @ full(x0) <= 0):
                continue
            r = least_squares(res, x0, jac=jac, bounds=(lo[free], hi[free]), method="trf",
                              xtol=1e-14, ftol=1e-14, gtol=1e-14)
            if best is None or r.cost < best.cost:
                best = r
        x = full(best.x) if best is not None else hi
    x = np.clip(x, lo, hi)
    return float(x[0] * sa), float(x[1] * sb)
