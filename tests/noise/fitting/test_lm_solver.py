"""The Levenberg–Marquardt kernel against its textbook form, bit for bit: the solver's arrays are allocated once,
LAPACK's dgesv is called without numba's copies, and a trial point that rounding left unmoved is rejected without
evaluating it; none of that may change a number."""

from __future__ import annotations

import numpy as np
from numba import njit

from imunoise.noise.fitting.kernels import levenberg_marquardt, wv_and_jacobian
from imunoise.noise.fitting.params import bounds, kind_codes
from imunoise.noise.fitting.problem import guided_starts, prepare
from imunoise.noise.model import Model
from imunoise.noise.processes import AR1, RW, WN


@njit(cache=True)
def textbook_lm(u0, kinds, tau, nuhat, W, lo, hi, max_iter, rtol):
    # the kernel as first written (every array fresh, np.linalg.solve, a trial always evaluated)
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
    for it in range(1, max_iter + 1):  # noqa: B007
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
            converged = True
            break
        if small_steps >= 3:
            converged = True
            break
    return u, f, it, converged


def test_solver_equals_its_textbook_form_bit_for_bit():
    truth = Model([AR1(phi=0.99, sigma2=1e-6), WN(sigma2=1e-4), RW(gamma2=1e-10)])
    x = truth.simulate(20_000, seed=3)
    problem = prepare(x, freq=100.0)
    n_runs = 0
    for structure in ("WN", "AR1 + WN", "2*AR1 + WN + RW", "3*AR1 + WN + QN + RW", "AR1 + WN + RW + DR"):
        kinds = kind_codes(Model.parse(structure))
        lo, hi = bounds(kinds)
        U = guided_starts(problem, kinds, 4, 0)
        eta = np.maximum(problem.wv.n_coefficients / problem.tau, 1.0)
        W_ql = np.ascontiguousarray(np.diag(np.sqrt(eta) / problem.nuhat_n))
        for W, max_iter, rtol in ((problem.W_n, 400, 1e-10), (W_ql, 100, 1e-10), (problem.W_n, 7, 1e-4)):
            for u0 in U:
                args = (u0.copy(), kinds, problem.tau, problem.nuhat_n, W, lo, hi, max_iter, rtol)
                got, ref = levenberg_marquardt(*args), textbook_lm(*args)
                assert got[0].tobytes() == ref[0].tobytes(), structure
                assert np.float64(got[1]).tobytes() == np.float64(ref[1]).tobytes()
                assert got[2:] == ref[2:]
                n_runs += 1
    assert n_runs == 5 * 3 * 10
