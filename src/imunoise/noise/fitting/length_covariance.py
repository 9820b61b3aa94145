"""The covariance of a fit's parameters at another record length L (docs/guide/theory.rst, 'Record length'); the
intervals and the lengths a target needs are :mod:`imunoise.export.record_length`.

The fit's own covariance is the GMM sandwich Cov(û) = A⁻¹BA⁻¹, A = GᵀΩG, B = GᵀΩVΩG
(:func:`imunoise.noise.fitting.problem.param_cov`), with V the covariance of ν̂. At another length only V, Ω and
the set of levels change; G = ∂ν/∂u stays the fitted model's.

* V, ``law="model"`` (the default): Percival's (1995) Gaussian asymptotic covariance of the Haar WV under the
  fitted model, level correlations included (:func:`model_wv_cov`). ``law="data"``: the V the fit used,
  rescaled per level as V_j(L₀)·M_j(L₀)/M_j(L) (Var ν̂_j = 2A_j/M_j), the η3 chi-square variance 2ν_j(θ̂)²/η_j
  (η_j = max(M_j/2^j, 1)) on a level the fit lacks; at L₀ it is the fit's own covariance exactly. The fit's V is
  diagonal, and its intervals under-cover (73 % and 69 % for N and K on 100 in-family records of 1 h); the
  correlated one covers at the nominal rate (docs/evidence/record_length.md).
* Ω follows the fit's weights: on a level the fit has, scaled by M_j(L)/M_j(L₀) (data-based weights, Ω ∝ V⁻¹;
  identity weights unchanged); on a level it lacks, the inverse of the η3 chi-square variance, in the fit's
  ratio of weight to variance.

M_j(L) = n − 2^j + 1 with n = L·f samples for one record (``fit``); for pooled stops (``calibrate``) a longer
calibration is more stops of the kind already seen, M_j(L) = M_j(L₀)·L/L₀ on the same levels, and the horizon
stays that of the longest stop. Levels are kept while M_j ≥ :data:`MIN_COEFFICIENTS` (as the WV estimator does)
and up to floor(log₂ n); the horizon is the top level's averaging time τ_J/(2f) (as
:func:`imunoise.noise.equivalent_noise.default_horizon_s`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.noise.fitting.kernels import wv_and_jacobian
from imunoise.noise.fitting.params import kind_codes, theta_to_u
from imunoise.noise.fitting.wvic import haar_gain, process_spectrum
from imunoise.noise.wv.accumulator import MIN_COEFFICIENTS

__all__ = ["LAWS", "record_length_s", "model_wv_cov", "predicted_cov", "horizon_at", "length_for_horizon"]

LAWS = ("model", "data")


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


def model_wv_cov(model: Any, tau: np.ndarray, m: np.ndarray, cache: dict | None = None) -> np.ndarray:
    """Percival's (1995) Gaussian asymptotic covariance of the Haar WV estimates under ``model``:
    Cov(ν̂_j, ν̂_k) = 2·min(M_j, M_k)/(M_j M_k)·∫ ``|H_j|²|H_k|²`` S² df over [−½, ½] (the integrand of
    :func:`imunoise.noise.fitting.wvic.wv_correlation`, here with its scale). ``cache``: the integrals per set of
    levels, kept by a caller that asks for many lengths of one model (they do not depend on M)."""
    key = np.asarray(tau, dtype=float).tobytes()
    A = None if cache is None else cache.get(key)
    if A is None:
        f, df, H = haar_gain(tau)
        S = process_spectrum(model, f)
        A = 2.0 * (H * (S * S * df)[None, :]) @ H.T  # the grid covers (0, ½]; the spectrum is even
        if cache is not None:
            cache[key] = A
    C = 2.0 * A * np.minimum.outer(m, m) / np.outer(m, m)
    return 0.5 * (C + C.T)


def predicted_cov(fit: Any, length_s: float, *, pooled: bool = False, record_s: float | None = None,
                  law: str = "model", cache: dict | None = None) -> np.ndarray:
    """Cov(û) of the fit's parameters for a record of ``length_s`` s (module docstring); same shape and the
    same not-identified parameters (infinite variance) as ``fit.param_cov_u``. ``law``: "model" (V from the
    fitted model's spectrum, the default) or "data" (the fit's own V rescaled: the fit's interval at L₀); ``cache``:
    see :func:`model_wv_cov`."""
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
        V = model_wv_cov(fit.model, tau, m, cache)
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
        A = Gi.T @ Om @ Gi
        d = np.sqrt(np.maximum(np.diag(A), 0.0))
        if not np.all(d > 0) or np.linalg.matrix_rank(A / np.outer(d, d), tol=1e-10) < A.shape[0]:
            return C  # too few levels at this length to identify the fitted parameters: every variance infinite
        A = np.linalg.pinv(A, hermitian=True)
        Ci = A @ (Gi.T @ Om @ V @ Om @ Gi) @ A
        C[np.ix_(ident, ident)] = 0.5 * (Ci + Ci.T)
    return C


def horizon_at(fit: Any, length_s: float, pooled: bool, record_s: float) -> float:
    """The horizon [s of averaging time] of a record of ``length_s`` s (module docstring)."""
    if pooled:  # the longest stop sets it: the fit's own top level
        return float(fit.wv.scales[-1]) / (2.0 * float(fit.freq))
    j, _ = _levels(fit, length_s, pooled, record_s)
    return 2.0 ** float(j[-1]) / (2.0 * float(fit.freq)) if j.size else math.nan


def length_for_horizon(fit: Any, horizon_s: float) -> float:
    """The shortest single record [s] (for pooled stops: the longest stop) whose top Haar level reaches an
    averaging time of ``horizon_s`` s: τ_J = 2^J ≥ 2·horizon·f with M_J = n − 2^J + 1 ≥ MIN_COEFFICIENTS."""
    if not (math.isfinite(horizon_s) and horizon_s > 0):
        raise ModelError(f"--target-horizon must be a positive time in seconds, got {horizon_s}")
    jj = max(1, math.ceil(math.log2(2.0 * horizon_s * float(fit.freq)) - 1e-12))
    return (2.0**jj + MIN_COEFFICIENTS - 1.0) / float(fit.freq)
