"""Compiled (numba) closed forms of the GMWM: model WV, its Jacobian, the objective and the
Levenberg–Marquardt solver (paper Eq. 6, docs/guide/theory.rst, 'Latent processes' and 'GMWM estimator').

The kernels work in the unconstrained parametrisation u of :mod:`imunoise.noise.fitting.params` on the
normalised problem (ν̂' = ν̂/c, W' = cW). Kind codes and the per-process numba forms come from the registry
(:data:`imunoise.noise.processes.PROCESS_TYPES`); the dispatch over kinds below is a compiled branch per registered
process (a new process adds its line in :func:`wv_and_jacobian` and :func:`wv_of_theta`).

numba's on-disk cache keys these kernels on this file only: after editing a process' numba form elsewhere,
touch this file (or clear ``__pycache__``) so the kernels recompile; ``tests/noise/test_process_registry.py`` compares
the compiled WV with the numpy closed form and fails on a stale cache.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types

from imunoise.noise.ar1_math import ar1_g
from imunoise.noise.fitting.ar1_levels import ar1_g_levels
from imunoise.noise.processes import AR1, DR, MA1, N_PARAMS, QN, RW, SIN, V_HI, WN

# kind codes and numba forms of the registry, frozen as compile-time constants of the kernels
_AR1, _WN, _QN, _RW, _DR = AR1.code, WN.code, QN.code, RW.code, DR.code
_WN_U, _QN_U, _RW_U, _DR_U = WN.nb_wv_u, QN.nb_wv_u, RW.nb_wv_u, DR.nb_wv_u
_AR1_T, _WN_T, _QN_T, _RW_T, _DR_T = AR1.nb_wv_theta, WN.nb_wv_theta, QN.nb_wv_theta, RW.nb_wv_theta, DR.nb_wv_theta
_MA1, _MA1_U, _MA1_T = MA1.code, MA1.nb_wv_u, MA1.nb_wv_theta
_SIN, _SIN_U, _SIN_T = SIN.code, SIN.nb_wv_u, SIN.nb_wv_theta
_NP = N_PARAMS

__all__ = ["ar1_g", "ar1_g_levels", "wv_and_jacobian", "objectives", "levenberg_marquardt", "wv_of_theta", "u_rows"]


@njit(cache=True)
def wv_and_jacobian(u, kinds, tau, nu, jac):
    """Model WV ν(u) and ∂ν/∂u (docs/guide/theory.rst, 'Latent processes') for the parametrisation of
    :mod:`imunoise.noise.fitting.params`.

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
    _wv_jac(u, kinds, tau, nu, jac, np.empty(J), np.empty(J), np.empty(P), np.empty(P, dtype=np.int64))


@njit(cache=True)
def _wv_jac(u, kinds, tau, nu, jac, g, gL, ar_exp, ar_idx):
    """:func:`wv_and_jacobian` with its scratch given (the solver allocates it once per solve): ``g``, ``gL``
    of shape (J,) for one AR1's levels, ``ar_exp`` (float) and ``ar_idx`` (int64) of shape (P,)."""
    J = tau.shape[0]
    P = u.shape[0]
    for j in range(J):
        nu[j] = 0.0
        for p in range(P):
            jac[j, p] = 0.0
    p = 0
    n_ar = 0
    v = 0.0
    for c in range(kinds.shape[0]):
        kind = kinds[c]
        if kind == _AR1:  # chained through the ordering of the correlation times (fitting.params)
            ar_idx[n_ar] = p
            if n_ar == 0:
                v = u[p]
            else:
                ar_exp[n_ar] = math.exp(u[p])  # level-free: once per component
                v = v + ar_exp[n_ar]
            n_ar += 1
            capped = v > V_HI + 1.0
            vv = min(v, V_HI + 1.0)
            L = -math.exp(vv)
            s2 = math.exp(u[p + 1])
            ar1_g_levels(tau, L, g, gL)
            for j in range(J):
                nu[j] += s2 * g[j]
                jac[j, p + 1] += s2 * g[j]
                if not capped:
                    dv = s2 * gL[j] * L  # dL/dv = L
                    jac[j, ar_idx[0]] += dv
                    for q in range(1, n_ar):
                        jac[j, ar_idx[q]] += dv * ar_exp[q]
        elif kind == _WN:
            _WN_U(u, p, tau, nu, jac)
        elif kind == _QN:
            _QN_U(u, p, tau, nu, jac)
        elif kind == _RW:
            _RW_U(u, p, tau, nu, jac)
        elif kind == _DR:
            _DR_U(u, p, tau, nu, jac)
        elif kind == _MA1:
            _MA1_U(u, p, tau, nu, jac)
        elif kind == _SIN:
            _SIN_U(u, p, tau, nu, jac)
        p += _NP[kind]


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


try:  # LAPACK's dgesv as numba's np.linalg.solve calls it (numba.np.linalg), without its copies and allocations
    from numba.np.linalg import _LAPACK, F_INT_nptype

    _XGESV = _LAPACK().numba_xgesv(types.float64)
except (ImportError, AttributeError):  # pragma: no cover - another numba layout: np.linalg.solve itself
    _XGESV = None
    F_INT_nptype = np.int32

if _XGESV is not None:

    @njit(cache=True)
    def _solve_into(M, b, MF, ipiv, x):  # pragma: no cover - compiled
        """x = np.linalg.solve(M, b) with the scratch given: the same checks and errors, the same LAPACK call on
        the same Fortran-ordered copy, so the same bits (MF, ipiv, x overwritten)."""
        P = M.shape[0]
        for i in range(P):
            for j in range(P):
                v = M[i, j]
                if not np.isfinite(v):
                    raise np.linalg.LinAlgError("Array must not contain infs or NaNs.")
                MF[j, i] = v
        for i in range(P):
            if not np.isfinite(b[i]):
                raise np.linalg.LinAlgError("Array must not contain infs or NaNs.")
            x[i] = b[i]
        r = _XGESV(ord("d"), P, 1, MF.ctypes, P, ipiv.ctypes, x.ctypes, P)
        if r != 0:
            raise np.linalg.LinAlgError("Matrix is singular to machine precision.")

else:  # pragma: no cover

    @njit(cache=True)
    def _solve_into(M, b, MF, ipiv, x):
        x[:] = np.linalg.solve(M, b)


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
        Box bounds of u (:func:`imunoise.noise.fitting.params.bounds`).
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
    gw, gLw, ar_exp, ar_idx = np.empty(J), np.empty(J), np.empty(P), np.empty(P, dtype=np.int64)
    # every array of the iterations allocated once: np.dot(a, b, out) is the BLAS call that ``a @ b`` makes
    # (numba computes ``a @ b`` as np.dot(a, b, np.empty(...))), so the numbers are the same
    r = np.empty(J)
    rn = np.empty(J)
    diff = np.empty(J)
    Jr = np.empty((J, P))
    A = np.empty((P, P))
    M = np.empty((P, P))
    g = np.empty(P)
    neg_g = np.empty(P)
    d = np.empty(P)
    un = np.empty(P)
    step = np.empty(P)
    MF = np.empty((P, P))
    ipiv = np.empty(P, dtype=F_INT_nptype)
    _wv_jac(u, kinds, tau, nu, jac, gw, gLw, ar_exp, ar_idx)
    for j in range(J):
        diff[j] = nuhat[j] - nu[j]
    np.dot(W, diff, r)
    f = np.dot(r, r)
    lam = 1e-3
    converged = False
    it = 0
    small_steps = 0
    for it in range(1, max_iter + 1):  # noqa: B007 (returned after the loop)
        np.dot(W, jac, Jr)
        for j in range(J):
            for i in range(P):
                Jr[j, i] = -Jr[j, i]
        np.dot(Jr.T, Jr, A)
        np.dot(Jr.T, r, g)
        dmax = 0.0
        for i in range(P):
            dmax = max(dmax, A[i, i])
        for i in range(P):
            d[i] = max(A[i, i], 1e-12 * dmax + 1e-300)
            neg_g[i] = -g[i]
        improved = False
        for _ in range(40):
            M[:, :] = A
            for i in range(P):
                M[i, i] += lam * d[i]
            _solve_into(M, neg_g, MF, ipiv, step)
            for i in range(P):
                # np.minimum(np.maximum(u + step, lo), hi), NaN kept
                x = u[i] + step[i]
                if x < lo[i]:
                    x = lo[i]
                if x > hi[i]:
                    x = hi[i]
                un[i] = x
            moved = False
            for i in range(P):  # un bit for bit u? (a signed zero counts as a move)
                moved = moved or un[i] != u[i] or math.copysign(1.0, un[i]) != math.copysign(1.0, u[i])
            if not moved:
                # the step vanished in rounding: the objective at un is f itself (the same numbers in, the same out),
                # not a descent; damp more, as the test below would
                lam *= 4.0
                if lam > 1e16:
                    break
                continue
            _wv_jac(un, kinds, tau, nu_n, jac_n, gw, gLw, ar_exp, ar_idx)
            for j in range(J):
                diff[j] = nuhat[j] - nu_n[j]
            np.dot(W, diff, rn)
            fn = np.dot(rn, rn)
            if fn < f and np.isfinite(fn):
                improved = True
                decrease = f - fn
                u[:] = un
                f = fn
                r[:] = rn
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
def u_rows(thetas, kinds, scale):  # pragma: no cover - compiled
    """u of every row of ``thetas`` (before clipping to the bounds), as the processes' ``u_from_theta`` walk of
    :func:`imunoise.noise.fitting.params.thetas_to_u` computes it: the same operations in the same order (Python's
    ``max(a, b)`` is ``b if b > a else a``, ``min(a, b)`` is ``b if b < a else a``, NaN kept), so the same bits;
    a test compares the two on every registered kind. ``ok`` is False for a kind without a compiled form here
    (the caller falls back to the processes' own walk).

    Parameters
    ----------
    thetas
        (n, P) natural parameter vectors of one structure.
    kinds
        Kind codes of the components.
    scale
        The normalisation c of the problem's WV.

    Returns
    -------
    U, ok
        (n, P) unconstrained parameters and whether every kind was known.
    """
    n, P = thetas.shape
    U = np.empty((n, P))
    hi_phi = 1.0 - 1e-15
    lo_ma = -1.0 + 1e-15
    for r in range(n):
        p = 0
        chain = 0.0
        chained = False
        for c in range(kinds.shape[0]):
            k = kinds[c]
            if k == _AR1:  # AR1.u_from_theta (the ordering chain of fitting.params)
                phi = thetas[r, p]
                if 1e-300 > phi:
                    phi = 1e-300
                if hi_phi < phi:
                    phi = hi_phi
                v = math.log(-math.log(phi))
                if not chained:
                    U[r, p] = v
                else:
                    x = v - chain
                    if 1e-9 > x:
                        x = 1e-9
                    U[r, p] = math.log(x)
                    v = chain + math.exp(U[r, p])
                chain = v
                chained = True
                x = thetas[r, p + 1] / scale
                if 1e-300 > x:
                    x = 1e-300
                U[r, p + 1] = math.log(x)
            elif k == _WN or k == _QN or k == _RW:  # Process.u_from_theta
                x = thetas[r, p] / scale
                if 1e-300 > x:
                    x = 1e-300
                U[r, p] = math.log(x)
            elif k == _DR:  # DR.u_from_theta
                x = abs(thetas[r, p]) / math.sqrt(scale)
                if 1e-150 > x:
                    x = 1e-150
                U[r, p] = math.log(x)
            elif k == _MA1:  # MA1.u_from_theta
                x = thetas[r, p]
                if lo_ma > x:
                    x = lo_ma
                if hi_phi < x:
                    x = hi_phi
                U[r, p] = math.atanh(x)
                x = thetas[r, p + 1] / scale
                if 1e-300 > x:
                    x = 1e-300
                U[r, p + 1] = math.log(x)
            else:
                return U, False
            p += _NP[k]
    return U, True


@njit(cache=True)
def wv_of_theta(theta, kinds, tau):  # pragma: no cover - compiled
    """Model WV from natural parameters (canonical order), components summed in that order
    (docs/guide/theory.rst, 'Latent processes').

    Parameters
    ----------
    theta
        Natural parameters in :attr:`imunoise.noise.model.Model.vector` order.
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
        if k == _AR1:
            _AR1_T(theta, p, tau, nu)
        elif k == _WN:
            _WN_T(theta, p, tau, nu)
        elif k == _QN:
            _QN_T(theta, p, tau, nu)
        elif k == _RW:
            _RW_T(theta, p, tau, nu)
        elif k == _DR:
            _DR_T(theta, p, tau, nu)
        elif k == _MA1:
            _MA1_T(theta, p, tau, nu)
        elif k == _SIN:
            _SIN_T(theta, p, tau, nu)
        p += _NP[k]
    return nu
