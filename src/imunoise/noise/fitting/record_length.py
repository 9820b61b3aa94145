"""How long to record: the 95 % interval of N and K and the horizon of a fitted axis as functions of the record
length L, and the length a target precision needs (docs/guide/theory.rst, 'Record length').

The fit's own interval is the delta method on the GMM sandwich Cov(û) = A⁻¹BA⁻¹, A = GᵀΩG, B = GᵀΩVΩG
(:func:`imunoise.noise.fitting.problem.param_cov`), with V the covariance of ν̂ the fit used. At another length
only V, Ω and the set of levels change; G = ∂ν/∂u stays the fitted model's:

* a level the fit has keeps its variance per coefficient: V_j(L) = V_j(L₀)·M_j(L₀)/M_j(L), the asymptotic law
  of the Haar WV estimator (Var ν̂_j = 2A_j/M_j for any spectrum, Percival 1995) — the measured variance of the
  record is rescaled, not replaced by a model's;
* a level the fit lacks (longer records reach coarser scales) gets the η3 chi-square variance the WV estimator
  itself assumes there, 2ν_j(θ̂)²/η_j with η_j = max(M_j/2^j, 1), from the fitted model's WV;
* Ω follows V as the fit's weights did (data-based weights: Ω = V⁻¹ per level; identity: unchanged).

M_j(L) = n − 2^j + 1 with n = L·f samples for one record (``fit``); for pooled stops (``calibrate``) a longer
calibration is more stops of the kind already seen, M_j(L) = M_j(L₀)·L/L₀ on the same levels, and the horizon
stays that of the longest stop. Levels are kept while M_j ≥ :data:`MIN_COEFFICIENTS` (as the WV estimator does)
and up to floor(log₂ n); the horizon is the top level's averaging time τ_J/(2f) (as
:func:`imunoise.noise.equivalent_noise.default_horizon_s`).

At L = L₀ the prediction is the fit's own interval exactly. The precision of a quantity is the half-width of its
interval relative to the value, ±100·(hi − lo)/(2·value) %. Coverage and the width a short pilot predicts for a
longer record are measured in docs/evidence/record_length.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.noise.fitting.kernels import wv_and_jacobian
from imunoise.noise.fitting.params import kind_codes, theta_to_u
from imunoise.noise.fitting.wvic import haar_gain, process_spectrum
from imunoise.noise.wv.accumulator import MIN_COEFFICIENTS

__all__ = ["QUANTITIES", "LengthPrediction", "record_length_s", "predict", "length_for", "length_for_horizon",
           "half_width_pct"]

QUANTITIES = {"N": "WN.noise_density", "K": "RW.random_walk"}
"""The exported pair's quantities and the fitted terms whose intervals they are."""
LAWS = ("model", "data")
_MAX_FACTOR = 1e4  # the inversion searches lengths up to this factor beyond the record


@dataclass(frozen=True)
class LengthPrediction:
    """What a record of ``length_s`` seconds would give: the intervals (low, high) of N and K [NaN when the model
    has no such term or the data do not identify it] and the horizon [s of averaging time]."""

    length_s: float
    horizon_s: float
    N: float
    N_ci: tuple[float, float]
    K: float
    K_ci: tuple[float, float]

    def pct(self, which: str) -> float:
        """Half-width of N's or K's interval in % of the value (NaN when not available)."""
        return half_width_pct(getattr(self, which), getattr(self, which + "_ci"))


def half_width_pct(value: float, ci: tuple[float, float]) -> float:
    """±100·(hi − lo)/(2·value) %: half the interval's width relative to the value."""
    lo, hi = ci
    if not (math.isfinite(lo) and math.isfinite(hi) and value > 0):
        return math.nan
    return 100.0 * (hi - lo) / (2.0 * value)


def record_length_s(fit: Any) -> float:
    """The length of the single record a fit's WV came from: n = M₁ + 1 samples (Haar level 1 has width 2)."""
    return (float(fit.wv.n_coefficients[0]) + 1.0) / float(fit.freq)


def _levels(fit: Any, length_s: float, pooled: bool, record_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(levels j, coefficient counts M_j) a record of ``length_s`` would give (module docstring)."""
    j0 = np.round(np.log2(np.asarray(fit.wv.scales, dtype=float))).astype(int)
    m0 = np.asarray(fit.wv.n_coefficients, dtype=float)
    if pooled:
        return j0, m0 * (length_s / record_s)
    n = length_s * float(fit.freq)
    top = int(math.floor(math.log2(n))) if n >= 2 else 0
    n_fit = record_s * float(fit.freq)
    if j0[-1] < int(math.floor(math.log2(n_fit))) and n_fit - 2.0 ** (j0[-1] + 1) + 1 >= MIN_COEFFICIENTS:
        top = min(top, int(j0[-1]))  # the fit was given fewer levels than its data allow (--max-scale): keep that
    j = np.arange(1, top + 1)
    m = n - 2.0**j + 1.0
    keep = m >= MIN_COEFFICIENTS
    return j[keep], m[keep]


def _weights_follow_v(fit: Any) -> bool:
    return not str(fit.weights).startswith(("identity", "custom"))


def model_wv_cov(model: Any, tau: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Percival's (1995) Gaussian asymptotic covariance of the Haar WV estimates under ``model``:
    Cov(ν̂_j, ν̂_k) = 2·min(M_j, M_k)/(M_j M_k)·∫ ``|H_j|²|H_k|²`` S² df over [−½, ½] (the integrand of
    :func:`imunoise.noise.fitting.wvic.wv_correlation`, here with its scale)."""
    f, df, H = haar_gain(tau)
    S = process_spectrum(model, f)
    A = 2.0 * (H * (S * S * df)[None, :]) @ H.T  # the grid covers (0, ½]; the spectrum is even
    C = 2.0 * A * np.minimum.outer(m, m) / np.outer(m, m)
    return 0.5 * (C + C.T)


def predicted_cov(fit: Any, length_s: float, *, pooled: bool = False, record_s: float | None = None,
                  law: str = "model") -> np.ndarray:
    """Cov(û) of the fit's parameters for a record of ``length_s`` s (module docstring); same shape and the
    same not-identified parameters (infinite variance) as ``fit.param_cov_u``. ``law``: "model" (V from the
    fitted model's spectrum, the default) or "data" (the fit's own V rescaled: the fit's interval at L₀)."""
    if law not in LAWS:
        raise ModelError(f"law must be one of {LAWS}, got {law!r}")
    if fit.param_cov_u is None or np.any(np.isnan(fit.param_cov_u)):
        raise ModelError(f"the fit of {fit.model} has no parameter covariance: no interval to predict")
    if not (math.isfinite(length_s) and length_s > 0):
        raise ModelError(f"a record length must be a positive time in seconds, got {length_s}")
    rec = record_length_s(fit) if record_s is None else float(record_s)
    j, m = _levels(fit, float(length_s), pooled, rec)
    if j.size == 0:
        raise ModelError(f"a record of {length_s:.3g} s holds no wavelet level with {MIN_COEFFICIENTS} coefficients")
    j0 = np.round(np.log2(np.asarray(fit.wv.scales, dtype=float))).astype(int)
    m0 = np.asarray(fit.wv.n_coefficients, dtype=float)
    om0 = fit.omega
    follow = _weights_follow_v(fit)
    # the V the fit's sandwich used: Ω⁻¹ for data-based weights (iterated ones included), else the WV's own
    v0 = np.linalg.inv(om0) if follow else np.asarray(fit.wv.cov, dtype=float)
    tau = 2.0 ** j.astype(float)
    kinds = kind_codes(fit.model)
    u = theta_to_u(fit.model.vector, kinds, 1.0)
    nu, G = np.empty(tau.size), np.empty((tau.size, u.size))
    wv_and_jacobian(u, kinds, tau, nu, G)
    V = np.zeros((tau.size, tau.size))
    Om = np.zeros_like(V)
    old = np.isin(j, j0)
    idx = np.searchsorted(j0, j[old])
    s = np.sqrt(m0[idx] / m[old])  # standard deviations scale as 1/√M_j
    V[np.ix_(old, old)] = v0[np.ix_(idx, idx)] * np.outer(s, s)
    Om[np.ix_(old, old)] = om0[np.ix_(idx, idx)] / (np.outer(s, s) if follow else 1.0)
    new = ~old
    if law == "model":
        V = model_wv_cov(fit.model, tau, m)
    elif new.any():
        V[new, new] = 2.0 * nu[new] ** 2 / np.maximum(m[new] / tau[new], 1.0)
    if new.any():
        # the estimator's weight on a level it has not seen: the fit's relation between a level's weight and its
        # variance (1 for Ω = V⁻¹), applied to the chi-square variance the WV estimator assumes there
        v_new = 2.0 * nu[new] ** 2 / np.maximum(m[new] / tau[new], 1.0)
        d_om, d_v = np.diag(om0), np.diag(v0)
        Om[new, new] = float(np.median(d_om * d_v)) / v_new if follow else float(np.median(d_om))
    cov0 = fit.param_cov_u
    ident = np.isfinite(np.diag(cov0))
    C = np.zeros_like(cov0)
    np.fill_diagonal(C, np.inf)
    if ident.any():
        Gi = G[:, ident]
        A = np.linalg.pinv(Gi.T @ Om @ Gi, hermitian=True)
        Ci = A @ (Gi.T @ Om @ V @ Om @ Gi) @ A
        C[np.ix_(ident, ident)] = 0.5 * (Ci + Ci.T)
    return C


def _horizon(fit: Any, length_s: float, pooled: bool, record_s: float) -> float:
    if pooled:  # the longest stop sets it: the fit's own top level
        return float(fit.wv.scales[-1]) / (2.0 * float(fit.freq))
    j, _ = _levels(fit, length_s, pooled, record_s)
    return 2.0 ** float(j[-1]) / (2.0 * float(fit.freq)) if j.size else math.nan


def predict(fit: Any, length_s: float, *, pooled: bool = False, record_s: float | None = None,
            level: float = 0.95, law: str = "model") -> LengthPrediction:
    """The intervals of N and K (the fitted WN and RW terms, :data:`QUANTITIES`) and the horizon a record of
    ``length_s`` seconds would give (module docstring). ``pooled``: the fit is of pooled stops whose total is
    ``record_s`` seconds (required then); else ``record_s`` defaults to the single record's length."""
    if pooled and record_s is None:
        raise ModelError("a pooled fit needs the total static time it came from (record_s)")
    rec = record_length_s(fit) if record_s is None else float(record_s)
    cov = predicted_cov(fit, length_s, pooled=pooled, record_s=rec, law=law)
    ci = replace(fit, param_cov_u=cov).confidence_intervals(level)
    cont = fit.continuous()
    nan2 = (math.nan, math.nan)
    vals = {k: (float(cont.get(q, math.nan)), tuple(ci.get(q, nan2))) for k, q in QUANTITIES.items()}
    return LengthPrediction(float(length_s), _horizon(fit, length_s, pooled, rec), vals["N"][0], vals["N"][1],
                            vals["K"][0], vals["K"][1])


def length_for(fit: Any, which: str, target_pct: float, *, pooled: bool = False, record_s: float | None = None,
               level: float = 0.95, law: str = "model") -> float:
    """The record length [s] at which ``which`` ("N" or "K") has a ±``target_pct`` % interval (bisection on
    log L between one level's worth of data and :data:`_MAX_FACTOR` times the record); inf when even that
    length does not reach it, NaN when the quantity has no interval."""
    if which not in QUANTITIES:
        raise ModelError(f"which must be one of {sorted(QUANTITIES)}, got {which!r}")
    if not (math.isfinite(target_pct) and target_pct > 0):
        raise ModelError(f"--target must be a positive percentage, got {target_pct}")
    rec = record_length_s(fit) if record_s is None else float(record_s)

    def pct(length: float) -> float:
        return predict(fit, length, pooled=pooled, record_s=rec, level=level, law=law).pct(which)

    here = pct(rec)
    if not math.isfinite(here):
        return math.nan
    if here > target_pct:
        lo, hi = rec, rec * _MAX_FACTOR
        if not pct(hi) <= target_pct:
            return math.inf
    else:
        shortest = (MIN_COEFFICIENTS + 1.0) / float(fit.freq)  # level 1 alone: n − 1 ≥ MIN_COEFFICIENTS
        lo, hi = max(rec / _MAX_FACTOR, shortest), rec
        if pct(lo) <= target_pct:
            return lo
    for _ in range(60):  # log-bisection: the half-width falls with L (monotone, see the tests)
        mid = math.sqrt(lo * hi)
        if pct(mid) > target_pct:
            lo = mid
        else:
            hi = mid
        if hi / lo < 1.0 + 1e-6:
            break
    return hi


def length_for_horizon(fit: Any, horizon_s: float) -> float:
    """The shortest single record [s] (for pooled stops: the longest stop) whose top Haar level reaches an
    averaging time of ``horizon_s`` s: τ_J = 2^J ≥ 2·horizon·f with M_J = n − 2^J + 1 ≥ MIN_COEFFICIENTS."""
    if not (math.isfinite(horizon_s) and horizon_s > 0):
        raise ModelError(f"--target-horizon must be a positive time in seconds, got {horizon_s}")
    jj = max(1, math.ceil(math.log2(2.0 * horizon_s * float(fit.freq)) - 1e-12))
    return (2.0**jj + MIN_COEFFICIENTS - 1.0) / float(fit.freq)
