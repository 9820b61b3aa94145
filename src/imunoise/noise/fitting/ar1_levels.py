"""The AR1 Haar WV and its derivative at every level of a scale grid, for the solver's kernels
(docs/guide/theory.rst, 'Latent processes'; numba).

The same operations on the same operands as :func:`imunoise.noise.ar1_math.ar1_g` at m = τ_j/2, so the same bits (tests
in ``tests/noise/fitting/test_ar1_levels.py``), with less work: what does not depend on the level (φ, expm1(L),
expm1(2L)
and their series tails) is computed once instead of once per level; on the dyadic grid (τ_{j+1} = 2τ_j) the
argument (2m+1)L of level j is (m'+1)L of level j+1, and 2mL is m'L, so a value is reused when its argument (and
the branch it was computed in) is exactly the same; the series tails stop once no later term can change the sum.
"""

from __future__ import annotations

import math

from numba import njit

__all__ = ["ar1_g_levels", "series_tail"]


@njit(cache=True)
def series_tail(x, order):
    """exp(x) − Σ_{n<order} xⁿ/n! as ``imunoise.noise.ar1_math._tail`` computes it, to the bit, stopping the series
    once a term is below 2⁻⁵⁵ of the sum: it cannot change the rounded sum, nor can any later term (smaller
    still, |x| < ½), so the remaining additions would all return the sum unchanged."""
    if abs(x) < 0.5:
        term = x**order
        for k in range(2, order + 1):
            term /= k
        acc = term
        normal = abs(acc) > 1e-290  # the ulp argument needs a normal sum
        for n in range(order + 1, order + 30):
            term = term * x / n
            if normal and abs(term) < abs(acc) * 2.0**-55:
                break
            acc += term
        return acc
    out = math.expm1(x) - x
    if order == 3:
        out -= 0.5 * x * x
    return out


@njit(cache=True)
def ar1_g_levels(tau, L, g, gL):
    """:func:`~imunoise.noise.ar1_math.ar1_g` at m = τ_j/2 for every level, into ``g`` and ``gL``
    (docs/guide/theory.rst, 'Latent processes').

    The same operations on the same operands as ``ar1_g(tau[j] / 2.0, L)``, so the same bits (a test checks
    it); what does not depend on the level (φ, expm1(L), expm1(2L) and their series tails) is computed once
    instead of once per level, and a term whose argument equals one of the previous level's is reused: the
    solver evaluates the AR1 WV at every step of every candidate.

    Parameters
    ----------
    tau
        Scales τ_j in samples.
    L
        ln φ (< 0).
    g, gL
        Outputs of shape (J,): ν_AR1(τ_j)/σ² and its derivative with respect to L.

    Returns
    -------
    None
    """
    phi = math.exp(L)
    e1 = math.expm1(L)
    e2 = math.expm1(2 * L)
    a = -e1
    b = -e2
    t31 = t32 = t21 = 0.0
    have3 = have2 = False
    # On the dyadic grid (τ_{j+1} = 2τ_j) the argument (2m+1)L of level j is (m'+1)L of level j+1, and 2mL is
    # m'L: a value is reused when its argument (and the branch it was computed in) is exactly the same.
    last_n, last_n_val, last_n_small = math.nan, 0.0, False
    last_d, last_d_val, last_d_small = math.nan, 0.0, False
    for j in range(tau.shape[0]):
        m = tau[j] / 2.0
        xa = (m + 1) * L
        xb = (2 * m + 1) * L
        if abs(xb) < 1.0:
            if not have3:
                t31, t32, have3 = series_tail(L, 3), series_tail(2 * L, 3), True
            fa = last_n_val if (xa == last_n and last_n_small) else series_tail(xa, 3)
            fb = series_tail(xb, 3)
            num = -3.0 * t31 - m * t32 + 4.0 * fa - fb
            last_n_small = True
        else:
            fa = last_n_val if (xa == last_n and not last_n_small) else math.expm1(xa)
            fb = math.expm1(xb)
            num = -3.0 * e1 - m * e2 + 4.0 * fa - fb
            last_n_small = False
        last_n, last_n_val = xb, fb
        xc = m * L
        xd = 2 * m * L
        if abs(xd) < 1.0:
            if not have2:
                t21, have2 = series_tail(L, 2), True
            fc = last_d_val if (xc == last_d and last_d_small) else series_tail(xc, 2)
            fd = series_tail(xd, 2)
            dnum = -2.0 * m * t21 + 4.0 * (m + 1) * fc - (2 * m + 1) * fd
            last_d_small = True
        else:
            fc = last_d_val if (xc == last_d and not last_d_small) else math.expm1(xc)
            fd = math.expm1(xd)
            dnum = -2.0 * m * e1 + 4.0 * (m + 1) * fc - (2 * m + 1) * fd
            last_d_small = False
        last_d, last_d_val = xd, fd
        den = 2.0 * m * m * a * a * b
        gj = num / den
        gphi = dnum / den + gj * 2.0 * (1.0 + 2.0 * phi) / b
        g[j] = gj
        gL[j] = gphi * phi
