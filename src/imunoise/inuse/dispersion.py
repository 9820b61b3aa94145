"""How much wider the in-motion estimate's intervals must be because its model family is not the truth: the
dispersion of a quasi-likelihood (docs/guide/theory.rst, 'In-use noise').

If the filter model were the truth, the per-fix scores s_k = ∂ℓ_k/∂θ of the prediction-error decomposition
would be martingale differences and their variance J = Var(Σ_k s_k) would equal the observed information H
(the information identity). Where the model is wrong (per-axis noise shared group-wide, real noise with more
long-scale power than the static part carries) the innovations are larger and correlated in time, J exceeds
H, and H⁻¹ is too narrow: the robust variance is H⁻¹JH⁻¹ (White 1982). One scalar per sensor group carries it,
the dispersion c = max(1, tr(H⁻¹J)/p) over the group's p identified parameters: intervals are widened by √c
(V = c H⁻¹) and likelihood ratios divided by c, as a quasi-likelihood with a dispersion parameter does. It is
never below 1: with one drive J is noisy, and the intervals the information gives are kept as a floor.

J is a heteroskedasticity- and autocorrelation-consistent estimate (Newey & West 1987, Bartlett weights) per
drive, summed over the drives (independent), its lag by Newey & West's (1994) rule from the scores' own
autocorrelation: long-scale model error correlates the scores over tens of fixes, which a fixed short lag
would miss.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = ["bandwidth", "dispersion", "hac", "score_variance"]


def bandwidth(x: np.ndarray) -> int:
    """Newey–West (1994) lag of the Bartlett kernel for the scalar series ``x`` (length T): pilot lag
    n = ⌊4 (T/100)^{2/9}⌋, s₀ = γ₀ + 2Σγ_j, s₁ = 2Σ jγ_j, lag = ⌊1.1447 ((s₁/s₀)² T)^{1/3}⌋, at most T − 1."""
    x = np.asarray(x, dtype=float) - float(np.mean(x))
    t = x.size
    if t < 3:
        return 0
    n = min(t - 1, int(4.0 * (t / 100.0) ** (2.0 / 9.0)))
    g = np.array([float(x[j:] @ x[: t - j]) / t for j in range(n + 1)])
    s0 = g[0] + 2.0 * float(np.sum(g[1:]))
    s1 = 2.0 * float(np.sum(np.arange(1, n + 1) * g[1:]))
    if not s0 > 0:
        return 0
    return int(min(t - 1, math.floor(1.1447 * ((s1 / s0) ** 2 * t) ** (1.0 / 3.0))))


def hac(s: np.ndarray, lag: int) -> np.ndarray:
    """Σ over lags j with ``abs(j) ≤ lag`` of the Bartlett-weighted ``(1 − abs(j)/(lag + 1))`` sums of
    s_k s_{k−j}ᵀ of the scores ``s`` (T × p), centred: the variance of their sum, T times the long-run
    covariance."""
    s = np.asarray(s, dtype=float)
    s = s - s.mean(axis=0)
    out = s.T @ s
    for j in range(1, lag + 1):
        c = s[j:].T @ s[:-j]
        out += (1.0 - j / (lag + 1.0)) * (c + c.T)
    return out


def score_variance(scores: Sequence[np.ndarray]) -> np.ndarray:
    """J of the module docstring: per drive the :func:`hac` of its scores (T_d × p) at the :func:`bandwidth` of
    their sum over the parameters, summed over drives."""
    p = scores[0].shape[1]
    out = np.zeros((p, p))
    for s in scores:
        if s.shape[0] >= 2:
            out += hac(s, bandwidth(s.sum(axis=1)))
    return out


def dispersion(H: np.ndarray, J: np.ndarray) -> float:
    """c = max(1, tr(H⁻¹J)/p) (module docstring); 1 where H is not positive definite or J not finite."""
    if H.size == 0 or not np.all(np.isfinite(J)):
        return 1.0
    try:
        L = np.linalg.cholesky(H)
    except np.linalg.LinAlgError:
        return 1.0
    c = float(np.trace(np.linalg.solve(L.T, np.linalg.solve(L, J)))) / H.shape[0]
    return max(1.0, c) if math.isfinite(c) else 1.0
