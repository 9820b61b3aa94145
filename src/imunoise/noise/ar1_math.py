"""The first-order autoregression's Haar wavelet variance in closed form, numpy and numba
(docs/guide/theory.rst, 'Latent processes' table).

The numpy form (:func:`ar1_wv`, :func:`ar1_wv_dphi`) serves :class:`imunoise.noise.processes.AR1`; the numba form
(:func:`ar1_g`) is the same formula written for the estimator's compiled kernels, and a test checks the two
equal on a grid of τ and φ. Both are cancellation-free for φ → 1.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["ar1_wv", "ar1_wv_dphi", "ar1_g"]


def _expm1_tail(x: np.ndarray, order: int) -> np.ndarray:
    """exp(x) − Σ_{n<order} xⁿ/n!, accurate for small |x| (order 2: expm1 − x; order 3: − x²/2 too).

    The AR1 closed form is a difference of powers of φ whose constant, linear and quadratic terms in
    log φ cancel exactly; writing it through these tails removes the catastrophic cancellation that the
    textbook form suffers for φ → 1 (e.g. φ = 0.9999 at τ = 2 loses ~12 digits otherwise).
    """
    x = np.asarray(x, dtype=float)
    out = np.empty_like(x)
    small = np.abs(x) < 0.5
    xs = x[small]
    term = xs**order / math.factorial(order)
    acc = term.copy()
    for n in range(order + 1, order + 30):
        term = term * xs / n
        acc += term
    out[small] = acc
    xl = x[~small]
    big = np.expm1(xl) - xl
    if order == 3:
        big = big - 0.5 * xl * xl
    out[~small] = big
    return out


def ar1_wv(tau: np.ndarray, phi: float, sigma2: float) -> np.ndarray:
    """Haar WV of a stationary AR1 with innovation variance σ² (docs/guide/theory.rst, 'Latent processes' table,
    cancellation-free).

    With m = τ/2, L = ln φ and F_k = e^{kL} − 1 − kL − (kL)²/2 the numerator equals
    −3F_1 − mF_2 + 4F_{m+1} − F_{2m+1} exactly, and the denominator is 2m²(1−φ)²(1−φ²).
    """
    tau = np.asarray(tau, dtype=float)
    m = tau / 2.0
    L = math.log(phi)

    # Tails where (2m+1)|L| is small (the cancelling regime), plain expm1 elsewhere: there the tails
    # would subtract huge polynomial terms instead.
    def num_with(order: int) -> np.ndarray:
        def e(x: np.ndarray) -> np.ndarray:
            return _expm1_tail(x, order) if order else np.expm1(x)

        return (
            -3.0 * e(np.full_like(m, L))
            - m * e(np.full_like(m, 2 * L))
            + 4.0 * e((m + 1) * L)
            - e((2 * m + 1) * L)
        )

    small = np.abs((2 * m + 1) * L) < 1.0
    num = np.where(small, num_with(3), num_with(0))
    one_m_phi = -math.expm1(L)
    one_m_phi2 = -math.expm1(2 * L)
    den = 2.0 * m * m * one_m_phi**2 * one_m_phi2
    return sigma2 * num / den


def ar1_wv_dphi(tau: np.ndarray, phi: float, sigma2: float) -> np.ndarray:
    """∂ν²/∂φ of the AR1 Haar WV (analytic; same cancellation-free tails as :func:`ar1_wv`).

    g = N/D, N' = −2mG_1 + 4(m+1)G_m − (2m+1)G_{2m} with G_k = e^{kL} − 1 − kL, and
    D'/D = −2(1+2φ)/(1−φ²), so g' = N'/D + g·2(1+2φ)/(1−φ²).
    """
    tau = np.asarray(tau, dtype=float)
    m = tau / 2.0
    L = math.log(phi)

    def dnum_with(order: int) -> np.ndarray:
        def e(x: np.ndarray) -> np.ndarray:
            return _expm1_tail(x, order) if order else np.expm1(x)

        return -2.0 * m * e(np.full_like(m, L)) + 4.0 * (m + 1) * e(m * L) - (2 * m + 1) * e(2 * m * L)

    small = np.abs(2 * m * L) < 1.0
    dnum = np.where(small, dnum_with(2), dnum_with(0))
    one_m_phi = -math.expm1(L)
    one_m_phi2 = -math.expm1(2 * L)
    den = 2.0 * m * m * one_m_phi**2 * one_m_phi2
    g = ar1_wv(tau, phi, 1.0)
    return sigma2 * (dnum / den + g * 2.0 * (1.0 + 2.0 * phi) / one_m_phi2)


@njit(cache=True)
def _tail(x: float, order: int) -> float:
    # exp(x) − Σ_{n<order} xⁿ/n! (the scalar form of _expm1_tail)
    if abs(x) < 0.5:
        term = x**order
        for k in range(2, order + 1):
            term /= k
        acc = term
        for n in range(order + 1, order + 30):
            term = term * x / n
            acc += term
        return acc
    out = math.expm1(x) - x
    if order == 3:
        out -= 0.5 * x * x
    return out


@njit(cache=True)
def ar1_g(m: float, L: float) -> tuple[float, float]:
    """AR1 Haar WV per unit innovation variance g and dg/dL at L = ln φ (docs/guide/theory.rst, 'Latent processes',
    stable form).

    Parameters
    ----------
    m
        Half the scale, τ/2 (samples).
    L
        ln φ (< 0).

    Returns
    -------
    g, dg_dL : float
        ν_AR1(τ)/σ² and its derivative with respect to L.
    """
    phi = math.exp(L)
    if abs((2 * m + 1) * L) < 1.0:
        num = (
            -3.0 * _tail(L, 3) - m * _tail(2 * L, 3) + 4.0 * _tail((m + 1) * L, 3) - _tail((2 * m + 1) * L, 3)
        )
    else:
        num = (
            -3.0 * math.expm1(L)
            - m * math.expm1(2 * L)
            + 4.0 * math.expm1((m + 1) * L)
            - math.expm1((2 * m + 1) * L)
        )
    if abs(2 * m * L) < 1.0:
        dnum = -2.0 * m * _tail(L, 2) + 4.0 * (m + 1) * _tail(m * L, 2) - (2 * m + 1) * _tail(2 * m * L, 2)
    else:
        dnum = (
            -2.0 * m * math.expm1(L) + 4.0 * (m + 1) * math.expm1(m * L) - (2 * m + 1) * math.expm1(2 * m * L)
        )
    a = -math.expm1(L)
    b = -math.expm1(2 * L)
    den = 2.0 * m * m * a * a * b
    g = num / den
    gphi = dnum / den + g * 2.0 * (1.0 + 2.0 * phi) / b
    return g, gphi * phi
