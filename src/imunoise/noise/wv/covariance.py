"""eta3 chi-square intervals and the diagonal covariance of nu^2 hat; the one place a
:class:`~imunoise.noise.wv.result.WaveletVariance` is finished from per-level sums
(docs/guide/theory.rst, 'Wavelet variance', paper Eq. 4).

Covariance of nu^2 (``WaveletVariance.cov``). Diagonal. Per level the long-run variance of W^2_{j,t} is
estimated by non-overlapping batch means (asymptotically the Bartlett lag-window estimate of the
spectral density of W^2 at frequency 0 with bandwidth = batch length B_j = max(2*tau_j, 256)
coefficients). Batches end where the time index inside a segment is a multiple of B_j, so they never
cross a segment end (first and last batch of a segment may be partial):

    V_bm = K/(K-1) * sum_b (S_b - n_b nu^2)^2 / M^2,   K = M^2 / sum_b n_b^2 (effective batch count).

With few batches (top levels) that estimate is itself very noisy, so it is shrunk towards the variance
the chi-square CI assumes, V_chi = 2 nu^4 / eta3 (eta3 = max(M/2**j, 1)), with a prior weight of
``COV_PRIOR_BATCHES`` = 4 pseudo-batches: V = ((K-1) V_bm + 4 V_chi) / (K - 1 + 4). Monte Carlo
(N = 2**15, white noise and AR1+AR1+WN+RW, 200 replicates): mean V / true Var(nu^2 hat) = 0.8-1.2 at
levels 1-10, then rising to 1.5-6 at the top four levels where the conservative eta3 prior dominates;
the per-realisation scatter of V is 12-20 % at the low levels. For the robust estimate the same is
applied to the influence function of the M-scale (prior divided by the 60 % efficiency). Off-diagonal
terms are 0: estimates of them from one realisation are noisy enough at the top levels to make the
GMWM weight matrix (the inverse) erratic, and a diagonal is positive definite by construction.
Entries are floored at 1e-14 * max(V) (and a tiny absolute value), so the matrix stays invertible even
for short or periodic data.
"""

from __future__ import annotations

import numpy as np
from scipy.special import gammaincinv

from imunoise.errors import DataError
from imunoise.noise.wv.result import WaveletVariance
from imunoise.noise.wv.robust import huber_efficiency

__all__ = ["COV_PRIOR_BATCHES", "chi2_ci", "finish", "shrunk_covariance"]

#: Prior weight (in batches) of the chi-square variance when shrinking the batch-means variance.
COV_PRIOR_BATCHES = 4.0


def chi2_ci(variance: np.ndarray, m: np.ndarray, scales: np.ndarray, alpha: float):
    """eta3 chi-square CI (docs/guide/theory.rst, 'Wavelet variance'): eta = max(M_j / 2**j, 1), [eta nu^2 / q_{1-a/2},
    eta nu^2 / q_{a/2}]."""
    eta = np.maximum(m / scales, 1.0)
    # chi-square quantiles as scipy.stats.chi2.ppf computes them, without its per-call overhead
    lo = eta * variance / (2.0 * gammaincinv(eta / 2.0, 1.0 - alpha / 2.0))
    hi = eta * variance / (2.0 * gammaincinv(eta / 2.0, alpha / 2.0))
    return lo, hi, eta


def shrunk_covariance(variance, m, eta, ss, ns, nn, prior_factor=1.0):
    """Diagonal covariance of nu^2 hat: shrunk batch means (see module docstring).

    ``prior_factor`` scales the chi-square prior variance (1/efficiency for the robust estimate).
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.maximum(ss - 2.0 * variance * ns + variance**2 * nn, 0.0)
        k_eff = np.where(nn > 0, m.astype(float) ** 2 / nn, 0.0)
        dof = np.maximum(k_eff - 1.0, 0.0)
        v_chi = prior_factor * 2.0 * variance**2 / eta
        v = (q * k_eff / m.astype(float) ** 2 + COV_PRIOR_BATCHES * v_chi) / (dof + COV_PRIOR_BATCHES)
    v = np.where(np.isfinite(v), v, 0.0)
    floor = max(float(v.max(initial=0.0)) * 1e-14, 1e-300)
    return np.diag(np.maximum(v, floor))


def finish(stats, min_coefficients, alpha, freq, robust, rob):
    j = np.arange(1, stats.shape[0] + 1)
    m = stats[:, 1].astype(np.int64)
    keep = m >= min_coefficients
    if not keep.any():
        raise DataError(
            f"no level has at least {min_coefficients} wavelet coefficients (longest segment too short); "
            "pass longer segments or a smaller min_coefficients"
        )
    j, m, st = j[keep], m[keep], stats[keep]
    scales = 2.0**j
    variance = st[:, 0] / m if rob is None else rob[keep, 0]
    lo, hi, eta = chi2_ci(variance, m, scales, alpha)
    if rob is None:
        cov = shrunk_covariance(variance, m, eta, st[:, 2], st[:, 3], st[:, 4])
    else:
        # batch means of u = nu^2 + IF(w), whose pooled mean equals nu^2 at the M-estimate
        cov = shrunk_covariance(
            rob[keep, 1], m, eta, rob[keep, 2], rob[keep, 3], rob[keep, 4], 1.0 / huber_efficiency()
        )
    return WaveletVariance(
        scales=scales,
        variance=variance,
        ci_low=lo,
        ci_high=hi,
        n_coefficients=m,
        cov=cov,
        freq=freq,
        robust=robust,
        alpha=alpha,
    )


# ---------------------------------------------------------------------------------------------------
# robust estimate
