"""Autonomous model selection over every sub-model of the complete model (paper §2.2,
docs/guide/theory.rst, 'Model selection').

All candidates are fitted on ONE shared problem (same WV, same Ω), so their GOFs (paper Eq. 8) are
comparable. Candidates are visited from small to large; each is started from the fits of its immediate
sub-models (the new process added at several amplitudes, a new AR1 at several correlation scales) plus
a few guided starts, and refined by the Levenberg–Marquardt kernel of :mod:`imunoise.noise.fitting.kernels`.

Nesting guarantee (GOF never increases from a model to one that nests it). The parameter space of a
bigger model contains every sub-model's solution with the extra process at negligible amplitude (the
lower parametrisation bound, e^-120 of the data scale, which adds nothing representable to ν). If a
candidate's refined optimum is not below the best GOF of its immediate sub-models, it is restarted from
that embedding; LM only accepts descending steps, so the result is at most the sub-model's GOF, and by
induction over the immediate sub-models at most the GOF of every nested model.

WVIC. The GOF always prefers the bigger of two nested models; the penalised criterion reported beside it
(and ranking when ``criterion="wvic"``) is defined and justified in :mod:`imunoise.noise.fitting.wvic`; its
functions stay importable from here.

The pieces live in :mod:`imunoise.noise.fitting`: the candidates (:mod:`~imunoise.noise.fitting.candidates`), fitting
one
from its sub-models (:mod:`~imunoise.noise.fitting.candidate_fit`) and the result
(:mod:`~imunoise.noise.fitting.ranking`);
``Candidate``, ``candidates`` and ``ModelRanking`` stay importable from here.
"""

from __future__ import annotations

import functools
import time
from typing import Any

import numpy as np

from imunoise.errors import DataError, FitError, ModelError
from imunoise.noise.fitting.arguments import check_unit
from imunoise.noise.fitting.blas import with_one_blas_thread
from imunoise.noise.fitting.candidate_fit import Solved, fit_candidate, to_fit
from imunoise.noise.fitting.candidates import Candidate, candidates
from imunoise.noise.fitting.estimate import data_span, refit
from imunoise.noise.fitting.problem import GMWMProblem, param_cov, prepare
from imunoise.noise.fitting.ranking import ModelRanking
from imunoise.noise.fitting.wvic import loglik_grid, wv_correlation, wv_deviance, wv_neg_loglik, wvic_penalty
from imunoise.noise.model import ModelLike, as_model, default_complete

__all__ = [
    "ModelRanking",
    "Candidate",
    "select_model",
    "refit",  # re-export: the estimator's home is imunoise.noise.estimator (deprecated path, kept working)
    "candidates",
    "fits_levels",
    "wvic_penalty",
    "wv_correlation",
    "wv_deviance",
    "wv_neg_loglik",
]


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


@functools.lru_cache(maxsize=8)
def _shared_grid(tau_bytes: bytes) -> tuple[np.ndarray, ...]:
    """:func:`~imunoise.noise.fitting.wvic.loglik_grid` of the scales, shared by the selections of the axes of one
    record (same length, same scales); read only."""
    grid = loglik_grid(np.frombuffer(tau_bytes, dtype=float).copy())
    for a in grid:
        a.flags.writeable = False
    return grid


def _data_freq(data: Any, freq: Any) -> float:
    """The sample rate of ``data``: ``freq`` for arrays (required), the one a WaveletVariance or
    GMWMProblem carries otherwise (a different ``freq`` is refused)."""
    from imunoise.noise.fitting.arguments import check_freq
    from imunoise.noise.wv import WaveletVariance

    wv = data.wv if isinstance(data, GMWMProblem) else data if isinstance(data, WaveletVariance) else None
    if wv is not None:
        own = float(wv.freq)
        if freq is not None and abs(check_freq(freq) - own) > 1e-9 * own:
            raise DataError(f"freq={freq!r} but the wavelet variance was computed at {own:g} Hz; drop freq")
        return own
    if freq is None:
        raise DataError("select_model needs the sample rate of the data: give freq=HZ (e.g. freq=100.0)")
    return check_freq(freq)


@with_one_blas_thread
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
    """Fit every non-empty sub-model of ``complete`` on one WV and Ω and rank them
    (docs/guide/theory.rst, 'Model selection', paper §2.2).

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
        A process, a Model or a model string (:func:`imunoise.noise.model.as_model`); default the paper's
        4*AR1+DR+WN+QN+RW.
    criterion
        ``"wvic"`` (default, as the CLI; :mod:`imunoise.noise.fitting.wvic`) or ``"gof"`` (paper Eq. 8, which
        always prefers the largest nested model).
    top
        Number of best fits that get parameter covariances (confidence intervals).
    weights, robust
        Weight matrix Ω and WV estimator, as for :func:`imunoise.noise.estimator.gmwm` (one fixed Ω).
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
    solved: dict[Candidate, Solved] = {}
    skipped: list[tuple[str, str]] = []
    memo: dict = {}  # what the candidates' starts share on this problem
    for i, cand in enumerate(cands):
        if not fits_levels(cand.n_params, J):
            skipped.append((str(cand), f"{cand.n_params} parameters on {J} wavelet levels: needs at least "
                                       f"{cand.n_params + 1} (more data)"))
        else:
            try:
                solved[cand] = fit_candidate(problem, cand, solved, n_random=n_random, n_local=n_local, seed=seed,
                                             memo=memo)
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
    gain = _shared_grid(problem.tau.tobytes())
    fits = [to_fit(problem, sol, unit, corr, penalty, span.get("n_samples"), gain) for sol in solved.values()]
    fits = rank_fits(fits, criterion)
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


TIE_RTOL = 1e-8
"""Criterion values closer than this (relative to max(1, |best|)) are a tie. Nested candidates often reach the
same effective fit (a bigger model with parts collapsed), and their GOF then differs only by rounding: on the
simulated drive of tests/online/test_motion_learner.py, moving IMU increments by one ulp flipped the online
identification between 2*AR1 + WN + QN + RW + DR and 4*AR1 + WN + QN (GOF 1.7973948766543268 against
…282) on 3 of 6 perturbations, and with it the final position by 1.6 cm. The solver stops at a relative
step of 1e-10, so 1e-8 is above its noise and far below any difference the criterion is meant to show."""


def rank_fits(fits: list, criterion: str) -> list:
    """``fits`` best first by ``criterion`` ('gof' or 'wvic'), fewer parameters first among equals.

    Among the fits whose criterion is within :data:`TIE_RTOL` of the best, the one with the fewest parameters
    (then the earliest candidate) ranks first, so rounding differences between machines do not decide which
    structure is identified. The rest follow by criterion value.
    """
    def value(f) -> float:
        return f.extra["wvic"] if criterion == "wvic" else f.objective

    order = sorted(range(len(fits)), key=lambda i: (value(fits[i]), fits[i].n_params, i))
    if not order:
        return []
    best = value(fits[order[0]])
    tol = TIE_RTOL * max(1.0, abs(best))
    tied = [i for i in order if value(fits[i]) - best <= tol]
    first = min(tied, key=lambda i: (fits[i].n_params, i))
    return [fits[first]] + [fits[i] for i in order if i != first]

