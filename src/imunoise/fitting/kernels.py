"""Compiled (numba) closed forms of the GMWM: model WV, its Jacobian, the objective and the
Levenberg–Marquardt solver (paper Eq. 6, SPEC §2 and §4).

The kernels work in the unconstrained parametrisation u of :mod:`imunoise.fitting.params` on the
normalised problem (ν̂' = ν̂/c, W' = cW); kind codes are those of :data:`~imunoise.fitting.params.KIND_CODE`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from imunoise.fitting.params import V_HI

__all__ = ["ar1_g", "wv_and_jacobian", "objectives", "levenberg_marquardt", "wv_of_theta"]


@njit(cache=True)
def _tail(x: float, order: int) -> float:
    # exp(x) − Σ_{n<order} xⁿ/n! (see imunoise.processes._expm1_tail)
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
    """AR1 Haar WV per unit innovation variance g and dg/dL at L = ln φ (SPEC §2, stable form).

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


@njit(cache=True)
def wv_and_jacobian(u, kinds, tau, nu, jac):
    """Model WV ν(u) and ∂ν/∂u (SPEC §2) for the parametrisation of :mod:`imunoise.fitting.params`.

    Parameters
    ----------
    u
        Unconstrained parameters (normalised scale).
    kinds
        Kind codes of the components.
    tau
        Scales τ_j in samples.
    nu, jac
        Output arrays of shape (J,) and (J, P), overwritten with ν(u) and ∂ν/∂u.

    Returns
    -------
    None
    """
    J = tau.shape[0]
    P = u.shape[0]
    for j in range(J):
        nu[j] = 0.0
        for p in range(P):
            jac[j, p] = 0.0
    p = 0
    n_ar = 0
    ar_idx = np.empty(P, dtype=np.int64)
    v = 0.0
    for c in range(kinds.shape[0]):
        kind = kinds[c]
        if kind == 0:
            ar_idx[n_ar] = p
            if n_ar == 0:
                v = u[p]
            else:
                v = v + math.exp(u[p])
            n_ar += 1
            capped = v > V_HI + 1.0
            vv = min(v, V_HI + 1.0)
            L = -math.exp(vv)
            s2 = math.exp(u[p + 1])
            for j in range(J):
                g, gL = ar1_g(tau[j] / 2.0, L)
                nu[j] += s2 * g
                jac[j, p + 1] += s2 * g
                if not capped:
                    dv = s2 * gL * L  # dL/dv = L
                    jac[j, ar_idx[0]] += dv
                    for q in range(1, n_ar):
                        jac[j, ar_idx[q]] += dv * math.exp(u[ar_idx[q]])
            p += 2
        else:
            val = math.exp(u[p])
            for j in range(J):
                t = tau[j]
                if kind == 1:
                    d = val / t
                elif kind == 2:
                    d = 6.0 * val / (t * t)
                elif kind == 3:
                    d = val * (t * t + 2.0) / (12.0 * t)
                else:
                    d = val * val * t * t / 16.0
                    jac[j, p] += 2.0 * d
                    nu[j] += d
                    continue
                nu[j] += d
                jac[j, p] += d
            p += 1


@njit(cache=True)
def _objective(u, kinds, tau, nuhat, W):
    J = tau.shape[0]
    nu = np.empty(J)
    jac = np.empty((J, u.shape[0]))
    wv_and_jacobian(u, kinds, tau, nu, jac)
    r = W @ (nuhat - nu)
    return r @ r


@njit(cache=True)
def objectives(U, kinds, tau, nuhat, W):
    """GMWM objective ‖W(ν̂ − ν(u))‖² (paper Eq. 6) at every row of ``U``.

    Parameters
    ----------
    U
        Candidate points, one u per row.
    kinds, tau
        Kind codes and scales (samples).
    nuhat, W
        Normalised empirical WV and weight root (Ω = WᵀW).

    Returns
    -------
    numpy.ndarray
        One objective value per row (may be non-finite).
    """
    out = np.empty(U.shape[0])
    for i in range(U.shape[0]):
        out[i] = _objective(U[i], kinds, tau, nuhat, W)
    return out


@njit(cache=True)
def levenberg_marquardt(u0, kinds, tau, nuhat, W, lo, hi, max_iter, rtol):
    """Levenberg–Marquardt (Marquardt scaling) on r(u) = W(ν̂ − ν(u)) within box bounds (paper Eq. 6).

    Parameters
    ----------
    u0
        Starting point (clipped to the bounds).
    kinds, tau, nuhat, W
        Kind codes, scales (samples), normalised empirical WV and weight root (Ω = WᵀW).
    lo, hi
        Box bounds of u (:func:`imunoise.fitting.params.bounds`).
    max_iter, rtol
        Iteration limit; converged after three accepted steps with relative decrease ≤ ``rtol``.

    Returns
    -------
    u, f, iterations, converged
        Best point, its objective, iterations used and whether a (local) minimum was reached.
    """
    J = tau.shape[0]
    P = u0.shape[0]
    u = np.minimum(np.maximum(u0, lo), hi)
    nu = np.empty(J)
    jac = np.empty((J, P))
    nu_n = np.empty(J)
    jac_n = np.empty((J, P))
    wv_and_jacobian(u, kinds, tau, nu, jac)
    r = W @ (nuhat - nu)
    f = r @ r
    lam = 1e-3
    converged = False
    it = 0
    small_steps = 0
    for it in range(1, max_iter + 1):  # noqa: B007 (returned after the loop)
        Jr = -(W @ jac)
        A = Jr.T @ Jr
        g = Jr.T @ r
        d = np.empty(P)
        dmax = 0.0
        for i in range(P):
            dmax = max(dmax, A[i, i])
        for i in range(P):
            d[i] = max(A[i, i], 1e-12 * dmax + 1e-300)
        improved = False
        for _ in range(40):
            M = A.copy()
            for i in range(P):
                M[i, i] += lam * d[i]
            step = np.linalg.solve(M, -g)
            un = np.minimum(np.maximum(u + step, lo), hi)
            wv_and_jacobian(un, kinds, tau, nu_n, jac_n)
            rn = W @ (nuhat - nu_n)
            fn = rn @ rn
            if fn < f and np.isfinite(fn):
                improved = True
                decrease = f - fn
                u = un
                f = fn
                r = rn
                nu[:] = nu_n
                jac[:, :] = jac_n
                lam = max(lam / 3.0, 1e-15)
                if decrease <= rtol * f + 1e-300:
                    small_steps += 1
                else:
                    small_steps = 0
                break
            lam *= 4.0
            if lam > 1e16:
                break
        if not improved:
            converged = True  # no descent direction left at any damping: a (local) minimum
            break
        if small_steps >= 3:
            converged = True
            break
    return u, f, it, converged


@njit(cache=True)
def wv_of_theta(theta, kinds, tau):  # pragma: no cover - compiled
    """Model WV from natural parameters (canonical order), components summed in that order (SPEC §2).

    Parameters
    ----------
    theta
        Natural parameters in :attr:`imunoise.model.Model.vector` order.
    kinds, tau
        Kind codes of the components and scales τ_j (samples).

    Returns
    -------
    numpy.ndarray
        ν(θ) at every scale.
    """
    nu = np.zeros(tau.shape[0])
    p = 0
    for c in range(kinds.shape[0]):
        k = kinds[c]
        for j in range(tau.shape[0]):
            t = tau[j]
            if k == 0:
                g, _ = ar1_g(t / 2.0, math.log(theta[p]))
                nu[j] += theta[p + 1] * g
            elif k == 1:
                nu[j] += theta[p] / t
            elif k == 2:
                nu[j] += 6.0 * theta[p] / (t * t)
            elif k == 3:
                nu[j] += theta[p] * (t * t + 2.0) / (12.0 * t)
            else:
                nu[j] += theta[p] * theta[p] * t * t / 16.0
        p += 2 if k == 0 else 1
    return nu
