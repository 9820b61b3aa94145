"""Quality of a fit against the data it was fitted to (docs/guide/theory.rst, 'Wavelet variance' and 'Interfaces'): the
WV band check that gates an export,
the exported (N, K) pair against the data's Allan variance, and the estimate of a selected structure.

Three pure checks, all against the **data**, never against another model:

* :func:`band_check`: the fitted model's WV ν_j(θ̂) against the empirical WV's (1 − α) band
  [``ci_low``, ``ci_high``] (the η3 chi-square interval of :mod:`imunoise.noise.wv`). A fit is *outside over a
  range of scales* (:attr:`BandCheck.refused`) when at least :data:`BAND_RUN` consecutive levels lie outside,
  or at least :data:`BAND_FRACTION` of the levels (and :data:`BAND_RUN` at the least); a level counts only
  where the model is also more than :data:`BAND_TOLERANCE` (10 %) away from ν̂. Why these numbers:
  each level's interval misses a right model with probability α = 0.05, adjacent Haar levels correlate by
  ≈ 0.5 (:func:`imunoise.noise.fitting.wvic.wv_correlation`), so one or two levels outside happen to right models
  (``band_departures`` reports runs of 2). Measured on right models, the selection's fit settled here: 0 of
  40 simulated WN+RW stop sets (6 stops of 20–60 s at 100 Hz) and 0 of 40 AR1+WN+RW records (2^15 samples)
  refused (no level outside in any of the 80; the selection's one-step estimate alone: 1 refused), while a
  misfit structure (WN on AR1+WN; every structure on drive_0708's vibrating stops) leaves 3 or more
  consecutive levels.
* :func:`pair_check`: the (N, K) pair an export writes, as the exact discrete WV of WN(σ² = N²f) + RW(γ² = K²/f)
  (Allan variance 2ν²_j at averaging time T_j = τ_j/2f), against the data's band over the matched averaging
  times: the worst factor between the pair's AV and the **data's** AV, and where the pair leaves the band.
  (:attr:`imunoise.export.AxisNoise.worst_ratio` compares the pair with the fitted model instead.)
* :func:`reestimate`: the parameters of a structure chosen by :func:`imunoise.noise.selection.select_model`,
  estimated as :func:`imunoise.noise.estimator.gmwm` estimates a given structure: the selection keeps one Ω built
  from ν̂ for every candidate, and weights built from ν̂ favour the levels whose estimate fell low (a model
  that undershoots a level by any factor costs at most η_j/2 there, :mod:`imunoise.noise.fitting.wvic`); the
  iterated GMM re-centres Ω on the fitted WV (:meth:`~imunoise.noise.fitting.problem.GMWMProblem.reweighted`).

:func:`within_band` combines them for ``calibrate`` and ``fit --auto``: the selected structure re-estimated,
checked, and when it leaves the band the selection's richer candidates (those that nest it, in ranking
order) re-estimated and checked in turn; the first inside is used, else the selected one is kept with the
reason.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imunoise.errors import DataError, FitError
from imunoise.noise.fitting.result import GMWMFit
from imunoise.noise.model import Model
from imunoise.noise.processes import RW, WN
from imunoise.noise.wv import WaveletVariance, scale_runs

__all__ = [
    "BAND_RUN",
    "BAND_FRACTION",
    "BAND_TOLERANCE",
    "MIN_DOF",
    "BandCheck",
    "PairCheck",
    "Settled",
    "band_check",
    "pair_check",
    "reestimate",
    "within_band",
]

BAND_RUN = 3
"""Consecutive WV levels outside the band that make a fit *outside over a range of scales* (module docstring)."""
BAND_FRACTION = 0.25
"""Fraction of the WV levels outside the band (at least :data:`BAND_RUN` levels) that does the same."""
MIN_DOF = 3.0
"""Equivalent degrees of freedom η3 = M_j/τ_j of a level the pair's worst factor is read on (the Allan
reading's rule, :data:`imunoise.noise.allan.MIN_DOF`)."""
BAND_TOLERANCE = 0.10
"""A level counts as outside only where the model's WV is also more than this fraction away from ν̂ (5 % in a
noise density): on long records the band is narrower than any consumer of the export can act on (ADIS16405,
10⁶ samples: ±0.4 % at τ = 0.02 s, where a 2*AR1 fit within 3 % of ν̂ at every level was outside at 5)."""


def _ranges_text(ranges: Sequence[tuple[float, float]]) -> str:
    return ", ".join(f"{a:.3g} s" if a == b else f"{a:.3g}–{b:.3g} s" for a, b in ranges)


@dataclass(frozen=True)
class BandCheck:
    """A model's WV against the empirical WV's band (:func:`band_check`).

    Attributes
    ----------
    tau_s : tuple of float
        Scales τ_j [s] of the levels.
    outside : tuple of bool
        Per level: the model's WV is outside the band (NaN counts as outside).
    ratio : tuple of float
        Per level: model WV / empirical WV.
    alpha : float
        Level of the band (0.05: the 95 % band).
    """

    tau_s: tuple[float, ...]
    outside: tuple[bool, ...]
    ratio: tuple[float, ...]
    alpha: float = 0.05

    @property
    def n_levels(self) -> int:
        return len(self.outside)

    @property
    def n_outside(self) -> int:
        return int(sum(self.outside))

    @property
    def runs(self) -> list[tuple[int, int]]:
        """(first, last) level index of each run of consecutive levels outside."""
        return scale_runs(np.asarray(self.outside, dtype=bool))

    @property
    def ranges_s(self) -> list[tuple[float, float]]:
        """(first, last) scale τ [s] of each run outside, finest first."""
        return [(self.tau_s[a], self.tau_s[b]) for a, b in self.runs]

    @property
    def longest_run(self) -> int:
        return max((b - a + 1 for a, b in self.runs), default=0)

    @property
    def refused(self) -> bool:
        """Outside over a range of scales: ≥ :data:`BAND_RUN` consecutive levels, or ≥ :data:`BAND_FRACTION`
        of them (and ≥ :data:`BAND_RUN`)."""
        need = max(BAND_RUN, math.ceil(BAND_FRACTION * self.n_levels))
        return self.longest_run >= BAND_RUN or self.n_outside >= need

    def text(self) -> str:
        """'outside the 95 % WV band at τ = 0.02–0.32 s, 1.28 s (6 of 11 scales)', or 'inside …'."""
        pct = f"{100 * (1 - self.alpha):g} %"
        if not self.n_outside:
            return f"inside the {pct} WV band at all {self.n_levels} scales"
        return (f"outside the {pct} WV band at τ = {_ranges_text(self.ranges_s)} ({self.n_outside} of "
                f"{self.n_levels} scales)")

    def to_dict(self) -> dict[str, Any]:
        return {"refused": self.refused, "n_levels": self.n_levels, "n_outside": self.n_outside,
                "longest_run": self.longest_run, "outside_tau_s": [list(r) for r in self.ranges_s],
                "rule": f">= {BAND_RUN} consecutive scales or >= {BAND_FRACTION:.0%} of the scales outside the band "
                        f"(and more than {BAND_TOLERANCE:.0%} from the data's WV)",
                "text": self.text()}


def band_check(wv: WaveletVariance, theoretical: np.ndarray) -> BandCheck:
    """A model's WV against the empirical WV's (1 − α) band, widened to ν̂·(1 ± :data:`BAND_TOLERANCE`) where
    it is narrower (module docstring).

    Parameters
    ----------
    wv : WaveletVariance
        The empirical WV with its band (``ci_low``, ``ci_high``).
    theoretical : numpy.ndarray
        The model's WV at ``wv.scales`` (e.g. :attr:`GMWMFit.theoretical_wv`).

    Returns
    -------
    BandCheck
    """
    nu = np.asarray(theoretical, dtype=float).reshape(-1)
    if nu.shape != wv.variance.shape:
        raise DataError(f"the model's WV has {nu.size} levels, the empirical WV {wv.variance.size}")
    lo = np.minimum(wv.ci_low, wv.variance / (1.0 + BAND_TOLERANCE))
    hi = np.maximum(wv.ci_high, wv.variance * (1.0 + BAND_TOLERANCE))
    outside = ~((nu >= lo) & (nu <= hi))  # NaN counts as outside
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = nu / wv.variance
    return BandCheck(tuple(float(t) for t in wv.scales / wv.freq), tuple(bool(o) for o in outside),
                     tuple(float(r) for r in ratio), float(wv.alpha))


@dataclass(frozen=True)
class PairCheck:
    """An exported (N, K) pair's Allan variance against the data's (:func:`pair_check`).

    Attributes
    ----------
    tau_range_s : tuple of float
        Averaging times T [s] compared (the pair's matched range ∩ the data's levels).
    worst_ratio : float
        Largest factor between the pair's AV and the data's AV there (≥ 1), on the levels with η3 ≥
        :data:`MIN_DOF` (all when none has).
    worst_at_s : float
        Averaging time of that factor [s].
    above : bool
        Whether the pair is above the data there.
    outside_s : tuple of (float, float)
        Runs of averaging times where the pair's AV leaves the data's band.
    n_points, n_outside : int
        Levels compared, and those outside the band.
    """

    tau_range_s: tuple[float, float]
    worst_ratio: float
    worst_at_s: float
    above: bool
    outside_s: tuple[tuple[float, float], ...]
    n_points: int
    n_outside: int

    def text(self) -> str:
        side = "above" if self.above else "below"
        s = (f"pair/data AV: worst {self.worst_ratio:.3g}× ({side} the data at T = {self.worst_at_s:.3g} s; "
             f"T = {self.tau_range_s[0]:.3g}–{self.tau_range_s[1]:.3g} s)")
        if self.outside_s:
            s += f", outside the data's band at T = {_ranges_text(self.outside_s)}"
        return s

    def to_dict(self) -> dict[str, Any]:
        return {"tau_range_s": list(self.tau_range_s), "worst_ratio": self.worst_ratio, "worst_at_s": self.worst_at_s,
                "pair_above_data": self.above, "outside_band_s": [list(r) for r in self.outside_s],
                "n_points": self.n_points, "n_outside": self.n_outside}


def pair_model(N: float, K: float, freq: float) -> Model:
    """The discrete model of a continuous (N, K) pair at ``freq``: WN(σ² = N²f) + RW(γ² = K²/f)
    (docs/guide/theory.rst, 'Latent processes')."""
    comps = [WN(sigma2=float(N) ** 2 * freq)]
    if K > 0:
        comps.append(RW(gamma2=float(K) ** 2 / freq))
    return Model(comps)


def pair_check(wv: WaveletVariance, N: float, K: float, tau_range_s: tuple[float, float] | None = None) -> PairCheck:
    """The (N, K) pair's Allan variance against the data's, with its band, over averaging times T (module docstring).

    Parameters
    ----------
    wv : WaveletVariance
        The data's WV (AV = 2ν² at T_j = τ_j/2f, band 2·[ci_low, ci_high]).
    N, K : float
        The pair [u/√Hz], [u/s/√Hz] as exported.
    tau_range_s : tuple of float, optional
        Averaging times [s] the pair was matched on (default: every level).

    Returns
    -------
    PairCheck
    """
    f = float(wv.freq)
    T = np.asarray(wv.scales, dtype=float) / (2.0 * f)
    sel = np.ones(T.size, dtype=bool)
    if tau_range_s is not None:
        lo, hi = tau_range_s
        sel = (T >= lo * (1 - 1e-9)) & (T <= hi * (1 + 1e-9))
    if not sel.any():
        raise DataError(f"no WV level inside the averaging times {tau_range_s} s")
    nu = pair_model(N, K, f).wv(wv.scales)[sel]
    data = wv.variance[sel]
    r = nu / data
    factor = np.maximum(r, 1.0 / r)
    # the worst factor on the levels an Allan reading may use (η3 ≥ MIN_DOF): a top level of one stop
    # (η3 = 1) can sit a factor 100 from any smooth curve and still hold it inside its band
    eta = np.maximum(wv.n_coefficients / wv.scales, 1.0)[sel]
    j = int(np.argmax(np.where(eta >= MIN_DOF, factor, -np.inf))) if (eta >= MIN_DOF).any() else int(np.argmax(factor))
    out = ~((nu >= wv.ci_low[sel]) & (nu <= wv.ci_high[sel]))
    Ts = T[sel]
    ranges = tuple((float(Ts[a]), float(Ts[b])) for a, b in scale_runs(out))
    return PairCheck((float(Ts[0]), float(Ts[-1])), float(factor[j]), float(Ts[j]), bool(r[j] > 1.0), ranges,
                     int(sel.sum()), int(out.sum()))


def reestimate(fit: GMWMFit, problem: Any) -> GMWMFit:
    """The selected structure estimated as :func:`imunoise.noise.estimator.gmwm` estimates a given one (module
    docstring): from the selection's estimate, Ω re-centred on the fitted WV (iterated GMM, two steps).

    Parameters
    ----------
    fit : GMWMFit
        A candidate of a ranking (its ``extra`` is kept, with ``estimate`` added).
    problem : imunoise.noise.fitting.problem.GMWMProblem
        The ranking's shared problem (``ranking.problem``).

    Returns
    -------
    GMWMFit
        The re-estimated fit (the same object when Ω is not data-based).
    """
    from imunoise.noise.fitting.estimate import gmwm

    if problem.weights not in ("efficient", "diagonal"):
        return fit
    try:
        new = gmwm(fit.model.unknown(), problem, freq=fit.freq, start=fit.model, n_random=0, unit=fit.unit)
    except (FitError, DataError) as exc:  # the selection's estimate stands, with why
        fit.extra["estimate"] = f"the selection's (one Ω from ν̂): the iterated estimate failed: {exc}"
        return fit
    new.extra = {**new.extra, **fit.extra, "estimate": "iterated GMM (Ω re-centred on the fitted WV twice, as gmwm)",
                 "selection_estimate": dict(fit.model.params)}
    return new


@dataclass
class Settled:
    """Outcome of :func:`within_band`: the fit used, its band check, and what was tried."""

    fit: GMWMFit
    band: BandCheck
    selected: str
    note: str | None = None
    tried: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {"selected": self.selected, "used": str(self.fit.model), "band": self.band.to_dict(),
                "note": self.note, "tried": self.tried}


def within_band(ranking: Any, fit: GMWMFit | None = None, *, max_tries: int | None = None) -> Settled:
    """The selected structure re-estimated and checked against the band; richer candidates when it leaves it.

    Parameters
    ----------
    ranking : imunoise.noise.selection.ModelRanking
        The selection (its fits in ranking order and its shared ``problem``).
    fit : GMWMFit, optional
        The chosen candidate (default ``ranking.best``).
    max_tries : int, optional
        Richer candidates tried at most (default all).

    Returns
    -------
    Settled
        The first fit inside the band (the selected one, else the best-ranked richer candidate that nests
        it), or the selected one with ``note`` saying why no richer one was used.
    """
    chosen = ranking.best if fit is None else fit
    first = reestimate(chosen, ranking.problem)
    band = band_check(first.wv, first.theoretical_wv)
    if not band.refused:
        return Settled(first, band, str(chosen.model))
    richer = [c for c in ranking.fits if c.model.n_params > chosen.model.n_params and c.model.nests(chosen.model)]
    tried: list[str] = []
    best_other: tuple[int, str] | None = None
    for cand in richer[: max_tries if max_tries is not None else len(richer)]:
        re = reestimate(cand, ranking.problem)
        b = band_check(re.wv, re.theoretical_wv)
        tried.append(f"{cand.model} (rank {cand.extra.get('rank', '?')}): {b.n_outside} of {b.n_levels} outside")
        if not b.refused:
            note = (f"{chosen.model} {band.text()}; the richer {re.model} (rank {cand.extra.get('rank', '?')} by "
                    f"{cand.extra.get('criterion', 'the criterion')}) stays inside: used")
            re.extra["retry"] = {"selected": str(chosen.model), "reason": band.text()}
            return Settled(re, b, str(chosen.model), note, tried)
        if best_other is None or b.n_outside < best_other[0]:
            best_other = (b.n_outside, str(cand.model))
    if not richer:
        why = "no richer candidate in the selection (the complete model is reached)"
    else:
        why = (f"none of the {len(tried)} richer candidates that nest it stays inside (closest: {best_other[1]}, "
               f"{best_other[0]} of {band.n_levels} scales outside)")
    return Settled(first, band, str(chosen.model), f"{chosen.model} {band.text()}; {why}", tried)
