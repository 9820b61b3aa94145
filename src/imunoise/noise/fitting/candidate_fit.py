"""Fitting one candidate of the selection from its immediate sub-models (paper §2.2,
docs/guide/theory.rst, 'Model selection').

Each candidate is started from the fits of its immediate sub-models (the new process added at several
amplitudes, a new AR1 at several correlation scales) plus a few guided starts, and refined by the
Levenberg–Marquardt kernel of :mod:`imunoise.noise.fitting.kernels`; the nesting guarantee is stated in
:mod:`imunoise.noise.selection`. :func:`to_fit` turns a solution into a :class:`GMWMFit` with its WVIC
(:mod:`imunoise.noise.fitting.wvic`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from imunoise.noise.fitting.candidates import SINGLE, Candidate, candidate_of
from imunoise.noise.fitting.estimate import compiled_gof, finish_solution, solve
from imunoise.noise.fitting.problem import GMWMProblem
from imunoise.noise.fitting.result import GMWMFit
from imunoise.noise.fitting.wvic import ql_estimate, wv_neg_loglik, wvic_penalty
from imunoise.noise.model import ORDER, Model
from imunoise.noise.processes import AR1, Process

__all__ = ["Solved", "fit_candidate", "to_fit"]

NEGLIGIBLE = 1e-300  # amplitude of an embedded process: clipped to the lower bound e^-120·scale


@dataclass
class Solved:
    """One candidate's solution on the shared problem (before its WVIC)."""

    model: Model  # fitted (natural parameters)
    theta: np.ndarray
    gof: float
    converged: bool
    iterations: int
    n_starts: int
    elapsed_s: float


def _embed_variants(
    problem: GMWMProblem, parent: Solved, kind: str, child: Candidate, memo: dict | None = None
) -> list[np.ndarray]:
    """Natural parameter vectors of ``child`` = parent's solution + one new process (several guesses).

    Each vector is what ``Model(parent components + [new]).vector`` is, written without building the model:
    the parent is canonical, so the new process goes where :class:`~imunoise.noise.model.Model` sorts it (after
    the AR1s of larger or equal φ, or after the processes before its kind in :data:`~imunoise.noise.model.ORDER`).
    The guesses of the new process depend on the data alone: ``memo`` (one dict per problem) keeps them by kind.
    """
    comps = parent.model.components
    base = parent.theta.tolist()
    guesses = memo.get(kind) if memo is not None else None
    if guesses is None:
        guesses = _new_process_guesses(problem, kind)
        if memo is not None:
            memo[kind] = guesses
    new = list(guesses)
    if kind == "AR1":
        # the zero-amplitude embedding (reproduces the parent's GOF)
        new.append(("AR1", (_free_phi(parent.model), NEGLIGIBLE)))
    out = []
    for k, values in new:
        if k != kind:
            continue  # (never: the registry's embedding is of its own kind) the child would not be this one
        off = _insert_at(comps, k, values)
        out.append(np.array(base[:off] + list(values) + base[off:], dtype=float))
    return out


def _new_process_guesses(problem: GMWMProblem, kind: str) -> list[tuple[str, tuple[float, ...]]]:
    """(kind, values) of the process added to a sub-model's fit at several amplitudes (an AR1 also at several
    correlation scales), read off the problem's WV; the AR1's zero-amplitude embedding is added per parent."""
    tau, nu = problem.tau, problem.wv.variance
    J = len(tau)
    new: list[tuple[str, tuple[float, ...]]] = []
    if kind == "AR1":
        # correlation scales spread over the grid: peak of the AR1 WV near τ ≈ 3.8 T (T in samples)
        levels = sorted(set(np.round(np.linspace(0, J - 1, min(J, 6))).astype(int).tolist()))
        for lev in levels:
            T = max(tau[lev] / 3.8, 0.05)
            phi = math.exp(-1.0 / T)  # in (0, 1): a valid AR1 (T ≥ 0.05)
            for frac in (0.5, 0.1):
                var_gm = frac * nu[lev] / 0.19
                new.append(("AR1", (phi, float(var_gm * (1.0 - phi * phi)))))
    else:
        for frac in (0.5, 0.1, 0.01, 0.0):
            proc = SINGLE[kind].embedding(frac, nu, tau)
            new.append((proc.kind, proc.values))
    return new


def _insert_at(comps: tuple[Process, ...], kind: str, values: tuple[float, ...]) -> int:
    """Offset in the parameter vector of ``Model(comps + (new,))`` where the new process' values sit (comps
    canonical)."""
    off = 0
    if kind == "AR1":
        phi = values[0]
        for c in comps:  # stable sort by decreasing φ: after every AR1 with φ ≥ the new one's
            if c.kind != "AR1" or not c.values[0] >= phi:
                break
            off += 2
        return off
    rank = ORDER.index(kind)
    for c in comps:
        if c.kind != "AR1" and ORDER.index(c.kind) > rank:
            break
        off += len(c.param_names)
    return off


def _free_phi(model: Model) -> float:
    """A φ for a new zero-amplitude AR1 that does not tie with the model's AR1s."""
    phis = sorted((c.values[0] for c in model.components if c.kind == "AR1"), reverse=True)
    if not phis:
        return 0.5
    lo = phis[-1]
    # halfway (in log correlation time) below the fastest AR1, or above it if it is very fast
    v = math.log(-math.log(lo))
    return math.exp(-math.exp(v + 1.0)) if v + 1.0 < 3.5 else math.exp(-math.exp(v - 0.5))


def fit_candidate(
    problem: GMWMProblem,
    cand: Candidate,
    solved: dict[Candidate, Solved],
    *,
    n_random: int,
    n_local: int,
    seed: int,
    memo: dict | None = None,
) -> Solved:
    """Fit one candidate on the shared problem from its fitted immediate sub-models (module docstring).

    Parameters
    ----------
    problem
        The selection's shared problem (one WV and Ω).
    cand
        The candidate structure.
    solved
        The candidates fitted so far (its sub-models among them: candidates are visited small first).
    n_random, n_local, seed
        Guided random starts added, starts refined by LM, and their seed
        (:func:`~imunoise.noise.fitting.estimate.solve`).
    memo
        One dict per problem, shared by its candidates: what their starts share is computed once.

    Returns
    -------
    Solved
        The fit, never above the GOF of its best immediate sub-model (nesting guarantee,
        :mod:`imunoise.noise.selection`).
    """
    t0 = time.perf_counter()
    structure = cand.model
    parents = [(solved[p], kind) for p, kind in cand.parents() if p in solved]
    starts: list[np.ndarray] = []
    for par, kind in parents:
        starts += _embed_variants(problem, par, kind, cand, memo)
    u, _, conv, iters, n_starts = solve(problem, structure, starts, n_random=n_random, n_local=n_local, seed=seed)
    model, gof = finish_solution(problem, structure, u)
    if parents:
        # nesting guarantee (module docstring): never above the best immediate sub-model
        best_par, best_kind = min(parents, key=lambda pk: pk[0].gof)
        if not gof <= best_par.gof:
            emb = _embed_zero(best_par, best_kind, cand)
            u2, _, conv2, it2, _ = solve(problem, structure, [emb], n_random=0, n_local=1, seed=seed, guided=False)
            iters += it2
            model2, gof2 = finish_solution(problem, structure, u2)
            if gof2 < gof:
                model, gof, conv = model2, gof2, conv2
            if not gof <= best_par.gof:
                # bit-exact fallback: the embedding itself reproduces the sub-model's WV exactly
                model = structure.with_vector(emb)
                gof = compiled_gof(problem, model)
                conv = best_par.converged
    return Solved(model, model.vector, gof, bool(conv), iters, n_starts, time.perf_counter() - t0)


def _embed_zero(parent: Solved, kind: str, child: Candidate) -> np.ndarray:
    comps = list(parent.model.components)
    if kind == "AR1":
        comps.append(AR1(phi=_free_phi(parent.model), sigma2=NEGLIGIBLE))
    else:
        comps.append(SINGLE[kind].negligible())
    m = Model(comps)
    assert candidate_of(m) == child
    return m.vector


def to_fit(
    problem: GMWMProblem,
    sol: Solved,
    unit: str,
    corr: np.ndarray | None,
    penalty: str,
    n: int | None,
    gain: tuple[np.ndarray, ...] | None = None,
) -> GMWMFit:
    """The :class:`GMWMFit` of a solved candidate with its WVIC in ``extra`` (:mod:`imunoise.noise.fitting.wvic`).

    Parameters
    ----------
    problem, sol
        The shared problem and the candidate's solution.
    unit
        Data unit of the fit.
    corr
        Level correlation for ``penalty="optimism"`` (None otherwise).
    penalty
        ``"bic"`` or ``"optimism"``.
    n
        Number of samples of the data (None: read off the WV).
    gain
        :func:`~imunoise.noise.fitting.wvic.loglik_grid` of the scales, shared by the candidates.

    Returns
    -------
    GMWMFit
        ``extra`` holds ``wvic``, ``wvic_penalty``, ``wvic_fit`` and ``effective_params``.
    """
    if penalty == "optimism":
        pen, rank = wvic_penalty(problem, sol.model, corr)
        fit_term = sol.gof
    else:
        n_eff = n if n else int(problem.wv.n_coefficients[0]) + 1
        pen, rank = sol.model.n_params * math.log(max(n_eff, 3)), float(sol.model.n_params)
        ql = ql_estimate(problem, sol.model)
        fit_term = min(wv_neg_loglik(problem.wv, sol.model, gain), wv_neg_loglik(problem.wv, ql, gain))
    return GMWMFit.from_problem(
        problem,
        sol.model,
        objective=sol.gof,
        converged=sol.converged,
        unit=unit,
        iterations=sol.iterations,
        n_starts=sol.n_starts,
        elapsed_s=sol.elapsed_s,
        extra={"wvic": fit_term + pen, "wvic_penalty": pen, "wvic_fit": fit_term, "effective_params": rank},
    )
