"""Autonomous model selection over every sub-model of the complete model (paper §2.2, SPEC §5).

All candidates are fitted on ONE shared problem (same WV, same Ω), so their GOFs (paper Eq. 8) are
comparable. Candidates are visited from small to large; each is started from the fits of its immediate
sub-models (the new process added at several amplitudes, a new AR1 at several correlation scales) plus
a few guided starts, and refined by the Levenberg–Marquardt kernel of :mod:`imunoise.fitting.kernels`.

Nesting guarantee (GOF never increases from a model to one that nests it). The parameter space of a
bigger model contains every sub-model's solution with the extra process at negligible amplitude (the
lower parametrisation bound, e^-120 of the data scale, which adds nothing representable to ν). If a
candidate's refined optimum is not below the best GOF of its immediate sub-models, it is restarted from
that embedding; LM only accepts descending steps, so the result is at most the sub-model's GOF, and by
induction over the immediate sub-models at most the GOF of every nested model.

WVIC. The GOF always prefers the bigger of two nested models; the penalised criterion reported beside it
(and ranking when ``criterion="wvic"``) is defined and justified in :mod:`imunoise.fitting.wvic`; its
functions stay importable from here.
"""

from __future__ import annotations

import csv
import itertools
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imunoise.errors import DataError, FitError, ModelError
from imunoise.fitting.arguments import check_unit
from imunoise.fitting.estimate import compiled_gof, data_span, finish_solution, refit, solve
from imunoise.fitting.problem import GMWMProblem, param_cov, prepare
from imunoise.fitting.result import GMWMFit
from imunoise.fitting.wvic import haar_gain, ql_estimate, wv_correlation, wv_deviance, wv_neg_loglik, wvic_penalty
from imunoise.model import Model, ModelLike, as_model, default_complete
from imunoise.processes import AR1, PROCESS_TYPES

__all__ = [
    "ModelRanking",
    "Candidate",
    "select_model",
    "refit",  # re-export: the estimator's home is imunoise.estimator (deprecated path, kept working)
    "candidates",
    "fits_levels",
    "wvic_penalty",
    "wv_correlation",
    "wv_deviance",
    "wv_neg_loglik",
]

# the processes a model holds at most once, in canonical order (the registry); AR1 is the repeated one
_SINGLE = {k: cls for k, cls in PROCESS_TYPES.items() if cls.singleton}
_SINGLE_ORDER = tuple(_SINGLE)
_NEGLIGIBLE = 1e-300  # amplitude of an embedded process: clipped to the lower bound e^-120·scale


# ----------------------------------------------------------------------------------------------
# Candidate enumeration
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Candidate:
    """One sub-model of the complete model: number of AR1s and the set of other processes."""

    n_ar1: int
    others: tuple[str, ...]  # canonical order of the registry (WN, QN, RW, DR, ...)

    @property
    def model(self) -> Model:
        comps = [AR1() for _ in range(self.n_ar1)] + [_SINGLE[k]() for k in self.others]
        return Model(comps)

    @property
    def n_params(self) -> int:
        return len(AR1.param_names) * self.n_ar1 + sum(len(_SINGLE[k].param_names) for k in self.others)

    @property
    def size(self) -> int:
        return self.n_ar1 + len(self.others)

    def parents(self) -> list[tuple[Candidate, str]]:
        """Immediate sub-models (one process removed) with the kind of the removed process."""
        out = []
        if self.n_ar1 >= 1 and self.size > 1:
            out.append((Candidate(self.n_ar1 - 1, self.others), "AR1"))
        if self.size > 1:
            for k in self.others:
                out.append((Candidate(self.n_ar1, tuple(o for o in self.others if o != k)), k))
        return out

    def __str__(self) -> str:
        return str(self.model)


def candidates(complete: ModelLike | None = None) -> list[Candidate]:
    """Every non-empty sub-model of ``complete`` (default 4*AR1+DR+WN+QN+RW: 5·16 − 1 = 79), small first.

    Parameters
    ----------
    complete
        A process, a Model or a model string; default :func:`imunoise.model.default_complete`.

    Returns
    -------
    list of Candidate
        Ordered by size, then number of parameters (the order :func:`select_model` fits them in).
    """
    complete = default_complete() if complete is None else as_model(complete)
    counts = complete.counts
    n_ar_max = counts.get("AR1", 0)
    singles = [k for k in _SINGLE_ORDER if counts.get(k, 0)]
    out = []
    for a in range(n_ar_max + 1):
        for r in range(len(singles) + 1):
            for subset in itertools.combinations(singles, r):
                if a + r > 0:
                    out.append(Candidate(a, tuple(subset)))
    out.sort(key=lambda c: (c.size, c.n_params, -c.n_ar1, [_SINGLE_ORDER.index(k) for k in c.others]))
    return out


def _candidate_of(model: Model) -> Candidate:
    counts = model.counts
    return Candidate(counts.get("AR1", 0), tuple(k for k in _SINGLE_ORDER if counts.get(k, 0)))


# ----------------------------------------------------------------------------------------------
# Ranking result
# ----------------------------------------------------------------------------------------------
@dataclass
class ModelRanking:
    """All candidate fits of :func:`select_model`, sorted best first by ``criterion``."""

    fits: list[GMWMFit]
    criterion: str
    skipped: list[tuple[str, str]] = field(default_factory=list)  # (structure, reason)
    top: int = 3
    elapsed_s: float = 0.0
    problem: GMWMProblem | None = None

    @property
    def best(self) -> GMWMFit:
        return self.fits[0]

    @property
    def top_fits(self) -> list[GMWMFit]:
        return self.fits[: self.top]

    def __len__(self) -> int:
        return len(self.fits)

    def by_structure(self, structure: str | Model) -> GMWMFit:
        """The fit of one structure, e.g. ``ranking.by_structure("2*AR1+WN+RW")``.

        Parameters
        ----------
        structure
            A model string or Model (parameters ignored).

        Returns
        -------
        GMWMFit
            Its fit (``ModelError`` if it was not fitted).
        """
        target = (Model.parse(structure) if isinstance(structure, str) else structure).unknown()
        for fit in self.fits:
            if fit.model.unknown() == target:
                return fit
        raise ModelError(f"{target} is not among the fitted candidates of this ranking")

    def rows(self) -> list[dict[str, Any]]:
        rows = []
        for rank, fit in enumerate(self.fits, start=1):
            rows.append(
                {
                    "rank": rank,
                    "model": str(fit.model),
                    "n_params": fit.n_params,
                    "gof": fit.objective,
                    "wvic": fit.extra["wvic"],
                    "penalty": fit.extra["wvic_penalty"],
                    "time_ms": 1e3 * fit.elapsed_s,
                    "skipped": "",
                }
            )
        for structure, reason in self.skipped:
            rows.append(
                {
                    "rank": "",
                    "model": structure,
                    "n_params": Model.parse(structure).n_params,
                    "gof": math.nan,
                    "wvic": math.nan,
                    "penalty": math.nan,
                    "time_ms": math.nan,
                    "skipped": reason,
                }
            )
        return rows

    def table(self, limit: int | None = None) -> str:
        """Plain-text ranking: model, #params, GOF (Eq. 8), WVIC, fit time; skipped candidates last.

        Parameters
        ----------
        limit
            Show only the best ``limit`` fits (None: all).

        Returns
        -------
        str
        """
        if limit is not None and (isinstance(limit, bool) or not isinstance(limit, int) or limit < 0):
            raise ModelError(f"limit must be a whole number ≥ 0 (0 = none, None = all), got {limit!r}")
        shown = self.fits if limit is None else self.fits[:limit]
        w = max([len(str(f.model)) for f in shown] + [len(s) for s, _ in self.skipped] + [5])
        head = f"{'rank':>4}  {'model':<{w}}  {'#par':>4}  {'GOF (Eq. 8)':>12}  {'WVIC':>12}  {'time ms':>8}"
        lines = [
            f"{len(self.fits)} candidates ranked by {self.criterion.upper()} "
            f"(all on one WV and Ω; total {1e3 * self.elapsed_s:.0f} ms)",
            head,
            "-" * len(head),
        ]
        for rank, fit in enumerate(shown, start=1):
            lines.append(
                f"{rank:>4}  {str(fit.model):<{w}}  {fit.n_params:>4}  {fit.objective:>12.6g}  "
                f"{fit.extra['wvic']:>12.6g}  {1e3 * fit.elapsed_s:>8.2f}"
            )
        if limit is not None and len(self.fits) > limit:
            lines.append(f"  ... {len(self.fits) - limit} more (ranking.table() shows all)")
        for structure, reason in self.skipped:
            lines.append(f"   -  {structure:<{w}}  skipped: {reason}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table(limit=10)

    def to_csv(self, path: str) -> None:
        """One row per candidate (skipped ones with their reason), GOF and WVIC both present.

        Parameters
        ----------
        path
            Output CSV file.
        """
        rows = self.rows()
        with open(path, "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(rows[0]) if rows else ["model"])
            writer.writeheader()
            for row in rows:
                writer.writerow({k: (f"{v:.10g}" if isinstance(v, float) else v) for k, v in row.items()})


# ----------------------------------------------------------------------------------------------
# Fitting machinery (shared problem, u-space of imunoise.fitting.params)
# ----------------------------------------------------------------------------------------------
@dataclass
class _Solved:
    model: Model  # fitted (natural parameters)
    theta: np.ndarray
    gof: float
    converged: bool
    iterations: int
    n_starts: int
    elapsed_s: float


def _embed_variants(problem: GMWMProblem, parent: _Solved, kind: str, child: Candidate) -> list[np.ndarray]:
    """Natural parameter vectors of ``child`` = parent's solution + one new process (several guesses)."""
    tau, nu = problem.tau, problem.wv.variance
    J = len(tau)
    comps = list(parent.model.components)
    variants: list[list] = []
    if kind == "AR1":
        # correlation scales spread over the grid: peak of the AR1 WV near τ ≈ 3.8 T (T in samples)
        levels = sorted(set(np.round(np.linspace(0, J - 1, min(J, 6))).astype(int).tolist()))
        for lev in levels:
            T = max(tau[lev] / 3.8, 0.05)
            phi = math.exp(-1.0 / T)
            for frac in (0.5, 0.1):
                var_gm = frac * nu[lev] / 0.19
                variants.append(comps + [AR1(phi=phi, sigma2=var_gm * (1.0 - phi * phi))])
        # the zero-amplitude embedding (reproduces the parent's GOF)
        phi0 = _free_phi(parent.model)
        variants.append(comps + [AR1(phi=phi0, sigma2=_NEGLIGIBLE)])
    else:
        for frac in (0.5, 0.1, 0.01, 0.0):
            variants.append(comps + [_SINGLE[kind].embedding(frac, nu, tau)])
    out = []
    for v in variants:
        m = Model(v)
        if _candidate_of(m) == child:
            out.append(m.vector)
    return out


def _free_phi(model: Model) -> float:
    """A φ for a new zero-amplitude AR1 that does not tie with the model's AR1s."""
    phis = sorted((c.values[0] for c in model.components if c.kind == "AR1"), reverse=True)
    if not phis:
        return 0.5
    lo = phis[-1]
    # halfway (in log correlation time) below the fastest AR1, or above it if it is very fast
    v = math.log(-math.log(lo))
    return math.exp(-math.exp(v + 1.0)) if v + 1.0 < 3.5 else math.exp(-math.exp(v - 0.5))


def _fit_candidate(
    problem: GMWMProblem,
    cand: Candidate,
    solved: dict[Candidate, _Solved],
    *,
    n_random: int,
    n_local: int,
    seed: int,
) -> _Solved:
    t0 = time.perf_counter()
    structure = cand.model
    parents = [(solved[p], kind) for p, kind in cand.parents() if p in solved]
    starts: list[np.ndarray] = []
    for par, kind in parents:
        starts += _embed_variants(problem, par, kind, cand)
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
    return _Solved(model, model.vector, gof, bool(conv), iters, n_starts, time.perf_counter() - t0)


def _embed_zero(parent: _Solved, kind: str, child: Candidate) -> np.ndarray:
    comps = list(parent.model.components)
    if kind == "AR1":
        comps.append(AR1(phi=_free_phi(parent.model), sigma2=_NEGLIGIBLE))
    else:
        comps.append(_SINGLE[kind].negligible())
    m = Model(comps)
    assert _candidate_of(m) == child
    return m.vector


def _to_fit(
    problem: GMWMProblem,
    sol: _Solved,
    unit: str,
    corr: np.ndarray | None,
    penalty: str,
    n: int | None,
    gain: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> GMWMFit:
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


# ----------------------------------------------------------------------------------------------
# Public API
# ----------------------------------------------------------------------------------------------
def fits_levels(n_params: int, n_levels: int) -> bool:
    """True when a model of ``n_params`` parameters can be selected on ``n_levels`` wavelet levels: p < J.

    The GMWM matches J empirical WV levels with p parameters (paper Eq. 6); J − p is the degrees of freedom
    left to test the fit (the GOF of Eq. 8 is asymptotically χ² with J − p degrees of freedom). With p = J
    the model interpolates the WV (GOF 0 for any data) and selection by GOF always picks it: 50 samples give
    J = 5 levels, on which a 5-parameter 2*AR1+RW would "win" without saying anything about the sensor.
    """
    return n_params < n_levels


def _data_freq(data: Any, freq: Any) -> float:
    """The sample rate of ``data``: ``freq`` for arrays (required), the one a WaveletVariance or
    GMWMProblem carries otherwise (a different ``freq`` is refused)."""
    from imunoise.fitting.arguments import check_freq
    from imunoise.wv import WaveletVariance

    wv = data.wv if isinstance(data, GMWMProblem) else data if isinstance(data, WaveletVariance) else None
    if wv is not None:
        own = float(wv.freq)
        if freq is not None and abs(check_freq(freq) - own) > 1e-9 * own:
            raise DataError(f"freq={freq!r} but the wavelet variance was computed at {own:g} Hz; drop freq")
        return own
    if freq is None:
        raise DataError("select_model needs the sample rate of the data: give freq=HZ (e.g. freq=100.0)")
    return check_freq(freq)


def select_model(
    data: Any,
    *,
    freq: float | None = None,
    complete: ModelLike | None = None,
    criterion: str = "wvic",
    top: int = 3,
    weights: str | np.ndarray = "efficient",
    robust: bool = False,
    unit: str = "u",
    seed: int = 0,
    n_random: int = 4,
    n_local: int = 3,
    progress: Any = None,
    penalty: str = "bic",
) -> ModelRanking:
    """Fit every non-empty sub-model of ``complete`` on one WV and Ω and rank them (SPEC §5, paper §2.2).

    A candidate needs more wavelet levels than parameters (p < J, :func:`fits_levels`): with p ≥ J it
    reproduces any WV exactly (GOF 0, no degree of freedom left to test it), so it is skipped and listed in
    ``ranking.skipped`` with the reason.

    Parameters
    ----------
    data
        1-D array, list of static segments (pooled WV), a WaveletVariance or a GMWMProblem.
    freq
        Sample rate in Hz, required for arrays (``DataError`` when missing: the continuous-time values
        depend on it); a WaveletVariance or GMWMProblem carries its own (a different ``freq`` is refused).
    complete
        A process, a Model or a model string (:func:`imunoise.model.as_model`); default the paper's
        4*AR1+DR+WN+QN+RW.
    criterion
        ``"wvic"`` (default, as the CLI; :mod:`imunoise.fitting.wvic`) or ``"gof"`` (paper Eq. 8, which
        always prefers the largest nested model).
    top
        Number of best fits that get parameter covariances (confidence intervals).
    weights, robust
        Weight matrix Ω and WV estimator, as for :func:`imunoise.estimator.gmwm` (one fixed Ω).
    unit
        ``"u"`` or a unit the CLI knows (else ``UnitError``).
    seed
        Seed of the random starts.
    n_random, n_local
        Guided random starts added per candidate and LM refinements per candidate.
    progress
        Optional callable ``progress(done, total, structure)`` (the CLI drives tqdm with it).
    penalty
        ``"bic"`` (WVIC = −2 log-likelihood of the WV + p·ln n, default) or ``"optimism"`` (GOF +
        Stebler's trace term).

    Returns
    -------
    ModelRanking
        All candidate fits, best first by ``criterion``; GOF and WVIC of each in ``fit.extra``.
    """
    t0 = time.perf_counter()
    if penalty not in ("bic", "optimism"):
        raise ModelError(f"unknown WVIC penalty {penalty!r}; use 'bic' (consistent) or 'optimism' (Efron)")
    if criterion not in ("gof", "wvic"):
        raise ModelError(f"unknown criterion {criterion!r}; use 'gof' (paper Eq. 8) or 'wvic'")
    if not isinstance(top, int) or top < 1:
        raise ModelError(f"top must be a positive whole number, got {top!r}")
    complete_model = default_complete() if complete is None else as_model(complete)
    unit = check_unit(unit)
    problem = prepare(data, freq=_data_freq(data, freq), weights=weights, robust=robust)
    J = len(problem.tau)
    cands = candidates(complete_model)
    solved: dict[Candidate, _Solved] = {}
    skipped: list[tuple[str, str]] = []
    for i, cand in enumerate(cands):
        if not fits_levels(cand.n_params, J):
            skipped.append((str(cand), f"{cand.n_params} parameters on {J} wavelet levels: needs at least "
                                       f"{cand.n_params + 1} (more data)"))
        else:
            try:
                solved[cand] = _fit_candidate(problem, cand, solved, n_random=n_random, n_local=n_local, seed=seed)
            except FitError as exc:
                skipped.append((str(cand), f"fit failed: {exc}"))
        if progress is not None:
            progress(i + 1, len(cands), str(cand))
    if not solved:
        raise DataError(
            f"no candidate could be fitted: the data give only {J} wavelet levels "
            f"({'; '.join(r for _, r in skipped[:2])}); use more data"
        )
    corr = None
    if penalty == "optimism":
        # level correlation under the best-fitting (most flexible) candidate, shared by all penalties
        ref = min(solved.values(), key=lambda sl: (sl.gof, -sl.model.n_params))
        corr = wv_correlation(ref.model, problem.tau, problem.wv.n_coefficients)
    span = data_span(data, problem.wv.freq, arrays_only=True)
    gain = haar_gain(problem.tau)
    fits = [_to_fit(problem, sol, unit, corr, penalty, span.get("n_samples"), gain) for sol in solved.values()]
    key = "wvic" if criterion == "wvic" else None
    fits.sort(key=lambda f: (f.extra["wvic"] if key else f.objective, f.n_params))
    for f in fits[:top]:
        f.param_cov_u = param_cov(problem, f.model)
    for rank, f in enumerate(fits, start=1):
        f.extra["rank"] = rank
        f.extra["criterion"] = criterion
        if span:
            f.extra["data_span"] = span
    return ModelRanking(
        fits=fits,
        criterion=criterion,
        skipped=skipped,
        top=top,
        elapsed_s=time.perf_counter() - t0,
        problem=problem,
    )
