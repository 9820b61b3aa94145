"""Robust wavelet variance: Huber M-estimate of scale of the W_{j,t} per level
(docs/guide/theory.rst, 'Wavelet variance').

rho(u) = min(u^2, c^2) with c = ``HUBER_C`` (60 % Gaussian efficiency, simts' default efficiency; breakdown
point beta/c^2 = 43 %). The covariance of the robust nu^2 is the batch-means estimate applied to its influence
function IF(w) = 2 s2 (rho(w/s) - beta) / D (see :mod:`imunoise.noise.wv.covariance`).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from imunoise.noise.wv.kernels import batch_size, batch_stats, huber_mean_rho, level_coefficients

__all__ = ["HUBER_BETA", "HUBER_C", "HUBER_D", "huber_efficiency", "huber_scale", "robust_stats"]

#: Huber tuning constant of the M-estimate of scale with rho(u) = min(u^2, c^2): 60 % Gaussian efficiency
#: (simts' default efficiency; simts itself uses Tukey's biweight), breakdown point beta/c^2 = 43 %.
HUBER_C = 1.2245090302333765


def _huber_constants(c: float) -> tuple[float, float, float]:
    """E rho(Z), Var rho(Z) and E[rho'(Z) Z] for rho(u) = min(u^2, c^2), Z ~ N(0, 1)."""
    from scipy.stats import norm

    p_in = 2.0 * norm.cdf(c) - 1.0
    tail = 1.0 - p_in
    phi = norm.pdf(c)
    e2 = p_in - 2.0 * c * phi
    e4 = 3.0 * p_in - 2.0 * phi * (c**3 + 3.0 * c)
    beta = e2 + c * c * tail
    var = e4 + c**4 * tail - beta**2
    return float(beta), float(var), float(2.0 * e2)


HUBER_BETA, _HUBER_VAR, HUBER_D = _huber_constants(HUBER_C)


def huber_efficiency(c: float = HUBER_C) -> float:
    """Gaussian efficiency of the M-scale with rho(u) = min(u^2, c^2) relative to the SD (= 1/2 / avar)."""
    _, var, d = _huber_constants(c)
    return 0.5 * d * d / var



def huber_scale(w: np.ndarray, c: float = HUBER_C) -> float:
    """Huber M-estimate of scale^2 of zero-mean ``w``: solves mean(min(w^2/s, c^2)) = E min(Z^2, c^2).

    Consistent for Gaussian w (Fisher-consistency constant beta = E min(Z^2, c^2)); 60 % efficient at
    the default ``HUBER_C``.
    """
    w2 = np.ascontiguousarray(np.asarray(w, dtype=float) ** 2)
    beta = _huber_beta(c)
    c2 = c * c
    s0 = float(np.median(w2)) / 0.454936423119572  # median of chi2_1
    if s0 <= 0.0:
        s0 = float(w2.mean())
        if s0 <= 0.0:
            return 0.0

    def h(log_s: float) -> float:
        return huber_mean_rho(w2, math.exp(log_s), c2) - beta

    lo, hi = math.log(s0) - 1.0, math.log(s0) + 1.0
    for _ in range(200):
        if h(lo) > 0:
            break
        lo -= 2.0
    for _ in range(200):
        if h(hi) < 0:
            break
        hi += 2.0
    return math.exp(brentq(h, lo, hi, xtol=1e-13, rtol=1e-15, maxiter=200))


def _huber_beta(c: float) -> float:
    return HUBER_BETA if c == HUBER_C else _huber_constants(c)[0]


def robust_stats(segments: list[np.ndarray], top: int) -> np.ndarray:
    """Per level: robust nu^2, then batch statistics of its influence function (columns 1..4)."""
    work = [(s - s.mean(), np.empty(s.shape[0])) for s in segments if s.shape[0] >= 2]
    out = np.zeros((top, 5))
    c2 = HUBER_C * HUBER_C
    m = 1
    for j in range(top):
        coeffs = []
        new_work = []
        for a, b in work:
            if a.shape[0] >= 2 * m:
                coeffs.append(level_coefficients(a, b, m))
                new_work.append((b, a))
        work = new_work
        if not coeffs:
            break
        s2 = huber_scale(np.concatenate(coeffs))
        out[j, 0] = s2
        bsize = batch_size(j + 1)
        # nu^2 hat - nu^2 ~ mean of IF, IF(w) = 2 s2 (rho(w/s) - beta) / D; use u = nu^2 + IF so the batch
        # means formula (centred on the pooled mean) applies unchanged.
        acc = np.zeros(4)
        total_n = 0
        for w in coeffs:
            r = np.minimum(w * w / s2, c2) if s2 > 0 else np.zeros_like(w)
            u = s2 + 2.0 * s2 * (r - HUBER_BETA) / HUBER_D
            acc[:3] += np.array(batch_stats(u, bsize, 2 * m - 1))
            acc[3] += u.sum()
            total_n += w.shape[0]
        mean_u = acc[3] / total_n
        out[j, 1] = mean_u
        out[j, 2:5] = acc[0], acc[1], acc[2]
        m *= 2
    return out

