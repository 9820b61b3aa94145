"""EXPERIMENTAL research code: the likelihood statistic of the learner (``MotionNoiseConfig(statistic="likelihood")``,
not frozen nor reported): decide and revert by likelihood-ratio tests on the shadows' one-step GNSS innovations.

Statistic. Every shadow filter processes every aided fix of a round; the batch loop returns each fix's one-step
innovation NLL ½(νᵀS⁻¹ν + log det S + 3 log 2π), S = HPHᵀ + R before the update
(:func:`~imunoise.nav.filter_loop.innovation_nll`). By the prediction-error decomposition their sum is the exact
−log likelihood of the fixes under the shadow's model, so ΔNLL_k = NLL_k − NLL_current summed over rounds scores
candidate k against the current model (negative: the fixes are more likely under k). It scores the covariance,
not only the mean: too little process noise makes the innovations large for S, too much inflates log det S.

Rule (the design diagnostic docs/evidence/in_motion_likelihood.md).

1. Choose, on the ``choose_rounds`` rounds after the warm ones: the in-motion candidate with the lowest ΔNLL < 0
   among those whose position NIS is inside its band (:func:`~imunoise.online.learner.decision.nis_ok`); the
   R-only nuisance candidates (the current model with the fixes' σ × ``r_scales``) are scored alike and the
   best of them is kept as the in-motion candidate's rival.
2. Confirm, on the ``confirm_rounds`` later rounds only (disjoint): LR = 2(NLL_current − NLL_k) above the χ²
   quantile at 1 − α/m with ``lr_df`` degrees of freedom (m in-motion candidates: Bonferroni over every
   candidate the choice could have picked), the same test against the best R-only candidate (a GNSS σ scale
   must not explain the fixes as well: an understated receiver σ is the case that fools the likelihood), the
   candidate's NIS inside its band, and the harm guard: the rehearsed-outage drift of the candidate (the old
   statistic, kept as a guard only) not worse than the current model's by more than ``harm_margin`` in mean
   log ratio over the rehearsed confirm rounds.
3. Revert, on the next search's choose rounds: LR = 2(NLL_current − NLL_previous) above the χ² quantile at
   1 − α (one comparison).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.stats import chi2

from imunoise.online.learner.candidates import describe, refine

__all__ = ["LrVerdict", "lr_threshold", "lr_test", "drift_harm", "LikelihoodRule"]


@dataclass(frozen=True)
class LrVerdict:
    """A likelihood-ratio decision: ``ok`` whether LR > ``threshold``, ``delta_nll`` = NLL(alternative) −
    NLL(reference) summed over ``n_rounds`` rounds, ``lr`` = −2·``delta_nll``, ``level`` the test's level."""

    ok: bool
    lr: float
    threshold: float
    delta_nll: float
    level: float
    n_rounds: int

    def evidence(self, prefix: str = "") -> dict:
        return {f"{prefix}lr": self.lr, f"{prefix}threshold": self.threshold, f"{prefix}delta_nll": self.delta_nll,
                f"{prefix}level": self.level, "n_rounds": self.n_rounds}


def lr_threshold(level: float, df: int) -> float:
    """χ²(df) quantile at 1 − ``level`` (the LR a change must exceed)."""
    return float(chi2.ppf(1.0 - level, df))


def lr_test(nll_alt: Sequence[float], nll_ref: Sequence[float], level: float, df: int) -> LrVerdict:
    """Whether the alternative's per-round NLLs beat the reference's: LR = 2 Σ(ref − alt) > χ²_df(1 − level)."""
    d = float(np.sum(np.asarray(nll_alt, dtype=float) - np.asarray(nll_ref, dtype=float)))
    lr = -2.0 * d
    thr = lr_threshold(level, df)
    return LrVerdict(bool(math.isfinite(lr) and lr > thr), lr, thr, d, float(level), len(nll_alt))


def drift_harm(scores_alt: Sequence[float], scores_ref: Sequence[float], margin: float) -> tuple[bool, float, int]:
    """The harm guard: (harmful, mean log drift ratio, rehearsed rounds) over the rounds both were rehearsed;
    harmful when the mean exceeds ``margin`` (no rehearsed round: no evidence of harm)."""
    d = np.asarray(scores_alt, dtype=float) - np.asarray(scores_ref, dtype=float)
    d = d[np.isfinite(d)]
    mean = float(d.mean()) if d.size else math.nan
    return bool(d.size > 0 and mean > margin), mean, int(d.size)


class LikelihoodRule:
    """The likelihood rule's decisions, a mixin of :class:`~imunoise.online.learner.core.MotionNoiseLearner`
    (reads and writes its search state: ``_specs``, ``_roles``, ``_nll``, ``_scores``, ``_shadows``, ...)."""

    def _lik_after_choose(self, t: float, nav: Any) -> None:
        c = self.config
        N = np.array(self._nll)  # rounds × shadows
        S = np.array(self._scores)
        if "previous" in self._roles:
            kp = self._roles.index("previous")
            v = lr_test(N[:, kp], N[:, 0], c.alpha, c.lr_df)
            if v.ok:
                self._log(t, "revert", switch=True, processes=describe(self.previous or ()),
                          from_processes=describe(self.spec), statistic="likelihood", **v.evidence())
                self.spec, self.previous = self.previous or (), None
                self._restart(nav)
                return
        dn = (N - N[:, [0]]).sum(axis=0)
        cand = [k for k, r in enumerate(self._roles) if r == "candidate"]
        rsc = [k for k, r in enumerate(self._roles) if r == "rscale"]
        allowed = [self._nis_check(k)[0] for k in cand]
        self.families = refine(self.families, self._best_per_family(dn, cand))
        ranking = {str(k): {"processes": describe(self._specs[k]), "delta_nll": float(dn[k]), "nis_inside": bool(a)}
                   for k, a in zip(cand, allowed, strict=True)}
        r_best = min(rsc, key=lambda k: dn[k]) if rsc else None
        r_info = ({"r_scale": self._rscale[r_best], "r_delta_nll": float(dn[r_best])} if r_best is not None else {})
        ok = [k for k, a in zip(cand, allowed, strict=True) if a and math.isfinite(dn[k]) and dn[k] < 0]
        if not ok:
            self._log(t, "refuse", stage="choose", statistic="likelihood", reason="no candidate explains the fixes "
                      "better than the current model inside its NIS band", n_rounds=len(self._nll),
                      candidates=ranking, **r_info)
            self._restart(nav)
            return
        k = min(ok, key=lambda j: dn[j])
        self._chosen, self._rival = k, r_best
        self._log(t, "choose", statistic="likelihood", processes=describe(self._specs[k]), delta_nll=float(dn[k]),
                  mean_log_ratio=float(np.nanmean(S[:, k] - S[:, 0])) if np.isfinite(S[:, k] - S[:, 0]).any()
                  else math.nan, n_rounds=len(self._nll), n_candidates=self._n_cands, candidates=ranking, **r_info)
        keep = {0, k} | ({r_best} if r_best is not None else set())
        self._shadows = [e if i in keep else None for i, e in enumerate(self._shadows)]
        self._scores, self._nll = [], []
        self._nis = np.zeros_like(self._nis)
        self._phase = "confirm"

    def _lik_after_confirm(self, t: float, nav: Any) -> None:
        c = self.config
        k, r = self._chosen, self._rival
        assert k is not None
        N = np.array(self._nll)
        S = np.array(self._scores)
        level = c.alpha / max(self._n_cands, 1)
        v = lr_test(N[:, k], N[:, 0], level, c.lr_df)
        vr = lr_test(N[:, k], N[:, r], level, c.lr_df) if r is not None else None
        harm, drift, n_drift = drift_harm(S[:, k], S[:, 0], c.harm_margin)
        nis_in, nis_info = self._nis_check(k)
        _, nis_cur = self._nis_check(0)
        ev = {**v.evidence(), "statistic": "likelihood", "n_candidates": self._n_cands,
              "processes": describe(self._specs[k]), "nis_position": nis_info[0], "nis_velocity": nis_info[1],
              "nis_position_current": nis_cur[0], "mean_log_ratio": drift, "n_rehearsed": n_drift,
              "harm_margin": c.harm_margin,
              **({"r_scale": self._rscale[r], **vr.evidence("r_")} if vr is not None else {})}
        reason = ("LR below its threshold" if not v.ok else
                  "a GNSS σ scale explains the fixes as well" if vr is not None and not vr.ok else
                  "NIS outside its band" if not nis_in else
                  "the rehearsed drift is worse (harm guard)" if harm else "")
        if not reason:
            self._log(t, "confirm", switch=True, from_processes=describe(self.spec), **ev)
            self.previous, self.spec = self.spec, self._specs[k]
        else:
            self._log(t, "refuse", stage="confirm", **{**ev, "reason": reason})
        self._restart(nav)
