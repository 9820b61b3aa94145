"""The learner's decision rule: choose on some rehearsal rounds, confirm on disjoint later rounds, revert.

Scores. A rehearsal round gives every shadow filter the log RMS horizontal drift of a rehearsed GNSS outage
(:mod:`imunoise.online.learner.shadows`); a candidate's evidence against the current model is the paired
difference d_r = s_r(candidate) − s_r(current) (log ratio of drifts: d < 0, the candidate drifts less). The
rounds are spaced ``every_s`` ≥ ``outage_s`` apart, so no two rehearsed outages share a sample.

Rule (:func:`choose`, :func:`confirm`, :func:`revert`).

1. Choose: over the C choose rounds of a search, the candidate with the lowest mean d among those whose NIS is
   inside its band (:func:`nis_ok`); none if no mean is < 0.
2. Confirm, on the K later rounds only (disjoint from the choose rounds): a one-sided paired t test of
   mean d < 0 at level α/m, m = the number of candidates of the search (Bonferroni over every candidate the
   choice could have picked; the selection was made on other rounds, so this is conservative), the mean below
   −``margin``, and the candidate's shadow NIS of GNSS position (and velocity where the filter is aided by it)
   inside the two-sided χ² band over the search's fixes. Otherwise refused.
3. Revert: after a switch, the previous model runs as a shadow in the next search; on that search's choose
   rounds (disjoint from the rounds that confirmed the switch) a one-sided t test at α of "previous better than
   current" reverts.

Every function is pure: it takes the score arrays and returns a verdict with its evidence (for the event log).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2
from scipy.stats import t as student_t

__all__ = ["Verdict", "paired_test", "nis_band", "nis_ok", "choose", "confirm", "revert"]


@dataclass(frozen=True)
class Verdict:
    """A decision and its evidence: ``ok`` whether it holds, ``mean`` the mean paired log-score difference,
    ``t`` its t statistic, ``p`` the one-sided p-value, ``level`` the level it was tested at, ``n`` rounds,
    ``reason`` in words when it does not hold."""

    ok: bool
    mean: float
    t: float
    p: float
    level: float
    n: int
    reason: str = ""

    def evidence(self) -> dict:
        return {"mean_log_ratio": self.mean, "t_stat": self.t, "p": self.p, "level": self.level, "n_rounds": self.n,
                **({"reason": self.reason} if self.reason else {})}


def paired_test(d: Sequence[float]) -> tuple[float, float, float]:
    """(mean, t, one-sided p of mean < 0) of paired differences ``d`` (t with n − 1 df; p = 1 for n < 2 or a
    zero spread with mean ≥ 0, 0 for a zero spread with mean < 0)."""
    x = np.asarray(d, dtype=float)
    n = x.size
    if n == 0:
        return math.nan, math.nan, 1.0
    mean = float(x.mean())
    if n < 2:
        return mean, math.nan, 1.0
    sd = float(x.std(ddof=1))
    if sd == 0.0:
        return mean, (-math.inf if mean < 0 else math.inf if mean > 0 else 0.0), (0.0 if mean < 0 else 1.0)
    tt = mean / (sd / math.sqrt(n))
    return mean, float(tt), float(student_t.cdf(tt, n - 1))


def nis_band(n_fixes: float, dof: int = 3, alpha: float = 0.01) -> tuple[float, float]:
    """Two-sided 1 − α band of the mean NIS of ``n_fixes`` fixes of ``dof`` each (χ² of dof·n / n)."""
    n = max(float(n_fixes), 1.0)
    lo, hi = chi2.ppf([alpha / 2, 1 - alpha / 2], dof * n) / n
    return float(lo), float(hi)


def nis_ok(nis_sum: Sequence[float], n_fixes: Sequence[float], dof: int = 3, alpha: float = 0.01,
           min_fixes: int = 10) -> tuple[bool, list[dict]]:
    """The NIS guard over measurement kinds (position, velocity, ...): every kind with at least ``min_fixes``
    fixes has its mean NIS inside its band (a kind the filter is not aided by has no fixes and does not count).
    Returns (ok, per kind {mean, band, n})."""
    ok = True
    info = []
    for s, n in zip(nis_sum, n_fixes, strict=True):
        if n < min_fixes:
            info.append({"n": int(n)})
            continue
        mean = s / n
        lo, hi = nis_band(n, dof, alpha)
        inside = bool(lo <= mean <= hi)
        ok = ok and inside
        info.append({"mean": float(mean), "band": [lo, hi], "n": int(n), "inside": inside})
    return ok, info


def choose(d: np.ndarray, allowed: Sequence[bool]) -> int | None:
    """Column of ``d`` (rounds × candidates, paired differences against the current model) with the lowest mean
    among the ``allowed`` ones, if that mean is < 0; else None."""
    if d.shape[0] == 0:
        return None
    mean = d.mean(axis=0)
    mean = np.where(np.asarray(allowed, dtype=bool) & np.isfinite(mean), mean, np.inf)
    k = int(np.argmin(mean))
    return k if mean[k] < 0 else None


def confirm(d: Sequence[float], m: int, alpha: float, margin: float, min_rounds: int) -> Verdict:
    """Confirmation of a chosen candidate on its own later rounds ``d``: one-sided t at ``alpha``/``m``, mean
    below −``margin``, at least ``min_rounds`` rounds."""
    level = alpha / max(int(m), 1)
    mean, tt, p = paired_test(d)
    n = len(d)
    if n < min_rounds:
        return Verdict(False, mean, tt, p, level, n, f"{n} confirmation rounds < {min_rounds}")
    if not mean < -margin:
        return Verdict(False, mean, tt, p, level, n, f"mean log ratio {mean:.4f} not below −{margin:g}")
    if not p < level:
        return Verdict(False, mean, tt, p, level, n, f"p {p:.3g} ≥ α/m = {level:.3g}")
    return Verdict(True, mean, tt, p, level, n)


def revert(d_prev: Sequence[float], alpha: float, min_rounds: int) -> Verdict:
    """Whether later rounds contradict a switch: ``d_prev`` = s(previous) − s(current) per round; reverts when
    its one-sided t test of mean < 0 holds at ``alpha`` on at least ``min_rounds`` rounds."""
    mean, tt, p = paired_test(d_prev)
    n = len(d_prev)
    ok = n >= min_rounds and mean < 0 and p < alpha
    return Verdict(ok, mean, tt, p, alpha, n, "" if ok else "the previous model is not better on these rounds")
