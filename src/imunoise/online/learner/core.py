"""The learner's state: searches of shadow filters, rounds, decisions (:mod:`imunoise.online.learner`).

A *search* starts the shadows from the live filter: the current model, the previous one after a switch (for
the revert test), and every candidate (:func:`~imunoise.online.learner.candidates.search_candidates`). Its
rounds: ``warm_rounds`` not scored, ``choose_rounds`` on which every shadow is scored and one candidate chosen
(:func:`~imunoise.online.learner.decision.choose`), then ``confirm_rounds`` on which only the current model and
the chosen candidate run (:func:`~imunoise.online.learner.decision.confirm`). Then a new search starts, its
σ scales refined around the best of this one (:func:`~imunoise.online.learner.candidates.refine`).

Cost per round (one round every ``every_s`` = 20 s of aided driving): per active shadow the kernel over
``outage_s`` (rehearsal) plus ``every_s`` (advance) of samples, 4000 samples at 100 Hz; warm and choose rounds
run 1 + m (+1 after a switch) shadows (m = 21 with the default families), confirm rounds 2. A search (1 warm,
4 choose, 6 confirm rounds) takes 220 s of aided driving; on development drives of the simulator a choose round
took ≈ 0.2 s CPU, a confirm round ≈ 0.02 s (docs/evidence/in_motion_learner.md).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.online.learner import decision
from imunoise.online.learner.candidates import (
    DPH,
    Spec,
    compose,
    departure_variance,
    describe,
    refine,
    search_candidates,
)
from imunoise.online.learner.config import MotionNoiseConfig, MotionNoisePrior
from imunoise.online.learner.likelihood import LikelihoodRule
from imunoise.online.learner.rehearsal import SampleBuffer, run_round

__all__ = ["MotionNoiseLearner"]


class MotionNoiseLearner(LikelihoodRule):
    """The learner the navigator owns when ``OnlineConfig.motion_noise`` is set (``statistic="likelihood"``:
    the decisions of :class:`~imunoise.online.learner.likelihood.LikelihoodRule`).

    The navigator calls :meth:`observe` / :meth:`observe_span` after filter steps with the samples, their raw
    static flags and the fixes it applied, :meth:`static_changed` when it swaps in a new static model,
    :meth:`compose` to build the filter's model, :meth:`departure_var` at a departure, and :meth:`poll` /
    :meth:`close` for a thread job. Decisions land in :attr:`history` (dicts with ``decision`` = choose,
    confirm, refuse or revert, and their evidence); ``switch`` in a dict says the live model changes.
    """

    def __init__(self, config: MotionNoiseConfig, rate_hz: float, lever: np.ndarray, *, worker: str = "inline"):
        self.config = config
        self.rate = float(rate_hz)
        self.lever = np.asarray(lever, dtype=float)
        self.worker = worker
        prior = config.prior
        self.spec: Spec = () if prior is None else prior.spec
        self.previous: Spec | None = None
        self.families = config.families if prior is None else prior.families
        self.n_prior = 0 if prior is None else prior.rounds
        self.t_start: float | None = None
        self.n_starts = 0
        self.n_rehearsals = 0
        self.n_searches = 0
        self.n_stale = 0  # searches stopped by a round without GNSS
        self.history: list[dict] = []
        self.round_s: list[float] = []  # compute time of each round [s] (the cost)
        self._all_scores: list[np.ndarray] = []
        self.buf = SampleBuffer(max(int(round(config.min_stop_s * self.rate)), 1))
        self._shadows: list[Any] | None = None
        self._specs: list[Spec] = []
        self._roles: list[str] = []
        self._rscale: list[float] = []  # GNSS σ factor per shadow (1 but for the likelihood's R-only rivals)
        self._lik = config.statistic == "likelihood"
        self._stale = False
        self._t_sh = math.nan
        self._static: list[tuple[float, list]] = []
        self._reset_search()
        self._executor: ThreadPoolExecutor | None = None
        self._future: Future | None = None

    # -- the model ----------------------------------------------------------------------------------
    def compose(self, static_models: Sequence[Any], spec: Spec | None = None) -> list:
        """``static_models`` with the learned processes ``spec`` (default the current ones)."""
        return compose(static_models, self.spec if spec is None else spec, self.rate)

    def departure_var(self) -> list[float] | None:
        """Per axis the bias variance the current model adds at a departure, or None."""
        return departure_variance(self.spec)

    @property
    def cands(self) -> list[Spec]:
        """The models of the current search's shadows (the current model first)."""
        return list(self._specs)

    @property
    def scores(self) -> list[np.ndarray]:
        """Every rehearsed round's scores (log RMS drift per shadow of its search; NaN where not run)."""
        return list(self._all_scores)

    @property
    def min_stop_n(self) -> int:
        return self.buf.min_stop_n

    def evidence(self) -> MotionNoisePrior:
        """What a next drive of the same IMU in the same vehicle starts with."""
        return MotionNoisePrior(self.spec, tuple(self.families), self.n_prior + self.n_rehearsals)

    def summary(self) -> dict:
        """The learned model and the counts (the ``motion_noise_end`` event, the exported metrics)."""
        g = next((p for p in self.spec if p.kind == "gm" and p.sensor == "gyro"), None)
        return {"processes": describe(self.spec), "sigma_dph": [g.sigma / DPH if g else 0.0] * 3,
                "tc_s": [g.tc_s if g else 0.0] * 3,
                "n_rehearsals": self.n_rehearsals, "n_prior": self.n_prior, "n_starts": self.n_starts,
                "n_searches": self.n_searches, "n_stale": self.n_stale,
                "elapsed_s": {"round_median_cpu": float(np.median(self.round_s)) if self.round_s else math.nan,
                              "rounds_cpu": float(np.sum(self.round_s)), "rounds": len(self.round_s)}}

    def static_changed(self, t: float, static_models: Sequence[Any]) -> None:
        """The navigator swapped in a new static model at filter time ``t``: the shadows take it at ``t``."""
        if self._shadows is not None:
            self._static.append((float(t), list(static_models)))

    # -- data ---------------------------------------------------------------------------------------
    def waiting(self) -> bool:
        """The shadows wait to (re)start at the next aided moving step: every sample with a fix is an event."""
        return self._shadows is None or self._stale

    def next_round_t(self) -> float:
        """Filter time from which the next round is due (the shadows running; inline worker)."""
        return self._t_sh + self.config.every_s

    def observe_span(self, t: np.ndarray, dth: np.ndarray, dv: np.ndarray, static: np.ndarray,
                     fixes: Sequence[tuple]) -> None:
        """Samples ``t`` (n,) none of which starts the shadows or runs a round: keep them and the fixes used."""
        self.buf.add(t, dth, dv, np.asarray(static, dtype=bool), self._t_sh)
        self.buf.fixes.extend(fixes)

    def observe(self, nav: Any, t: float, dth: np.ndarray, dv: np.ndarray, static: bool,
                fixes: Sequence[tuple]) -> None:
        """One filter step of the navigator ``nav`` (after the fixes ``fixes`` were applied at ``t``). Starts
        the shadows at the first aided moving step; runs a round when one is due."""
        self.buf.add(np.array([t]), np.reshape(dth, (1, 3)), np.reshape(dv, (1, 3)), np.array([bool(static)]),
                     self._t_sh)
        self.buf.fixes.extend(fixes)
        c = self.config
        if self._shadows is None or self._stale:
            if fixes and nav.ekf.view.speed_h >= c.min_speed_mps and self._future is None:
                self._start(nav, t)
            return
        if self._future is not None or t < self._t_sh + c.every_s:
            return
        job = self._job()
        if job is None:
            return
        if self.worker == "thread":
            if self._executor is None:
                self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="imunoise-motion")
            self._future = self._executor.submit(self._timed_round, job)
            return
        self._decide(self._timed_round(job), nav)

    def _start(self, nav: Any, t: float) -> None:
        """A new search: shadows from the live filter (``nav.ekf``) with the current, previous and candidate
        models."""
        if self.t_start is None:
            self.t_start = float(t)
        self.n_starts += 1
        self._new_search(nav)
        self._t_sh = float(t)
        self.buf.fixes = [f for f in self.buf.fixes if f[0] > t]
        self.buf.restart_at_last()

    def _new_search(self, nav: Any) -> None:
        self._stale = False
        self._static = []
        self.n_searches += 1
        specs = [self.spec]
        roles = ["current"]
        if self.previous is not None:
            specs.append(self.previous)
            roles.append("previous")
        for s in search_candidates(self.spec, self.families):
            if s not in specs:
                specs.append(s)
                roles.append("candidate")
        self._rscale = [1.0] * len(specs)
        if self._lik:  # the R-only nuisance candidates: the current model with the fixes' σ scaled
            for r in self.config.r_scales:
                specs.append(self.spec)
                roles.append("rscale")
                self._rscale.append(float(r))
        self._specs, self._roles = specs, roles
        self._shadows = []
        for s in specs:
            e = copy.deepcopy(nav.ekf)
            e.swap_model(self.compose(nav.static_models, s), preserve=True)
            self._shadows.append(e)
        self._reset_search()

    def _reset_search(self) -> None:
        self._round = 0
        self._phase = "warm"
        self._scores: list[np.ndarray] = []
        self._nll: list[np.ndarray] = []
        self._nis = np.zeros((len(self._specs), 4))
        self._chosen: int | None = None
        self._rival: int | None = None
        self._n_cands = sum(r == "candidate" for r in self._roles)

    def _job(self) -> dict | None:
        """The data of the next round (copied, so a thread can run it), or None in a stretch without GNSS."""
        c, b = self.config, self.buf
        t0, t1 = self._t_sh, self._t_sh + c.every_s
        tb = b.t[: b.n]
        i0 = int(np.searchsorted(tb, t0, side="left"))
        i1 = int(np.searchsorted(tb, t1, side="right"))
        if i0 >= b.n or abs(tb[i0] - t0) > 1e-9:
            return None
        ft = np.array([f[0] for f in b.fixes]) if b.fixes else np.zeros(0)
        adv = np.nonzero((ft > t0) & (ft <= tb[i1 - 1]))[0]
        if adv.size == 0:
            # no GNSS for a whole round (an outage): nothing to score, nothing to learn; the shadows restart from
            # the live filter when fixes return
            self._stale = True
            self.n_stale += 1
            return None
        out = np.nonzero((ft > t0) & (ft <= t0 + c.outage_s))[0]
        statics = [s for s in self._static if s[0] <= tb[i1 - 1]]
        self._static = [s for s in self._static if s[0] > tb[i1 - 1]]
        i_out = int(np.searchsorted(tb, t0 + c.outage_s, side="right"))
        job = {"t": tb[i0:i1].copy(), "n_out": i_out - i0, "dth": b.dth[i0:i1].copy(), "dv": b.dv[i0:i1].copy(),
               "dep": b.dep[i0:i1].copy(), "n_adv": i1 - i0, "adv": b.fix_arrays(adv), "out": b.fix_arrays(out),
               "statics": statics, "shadows": self._shadows, "specs": list(self._specs)}
        if self._lik:
            job.update(nll=True, rscale=list(self._rscale))
        self._t_sh = float(tb[i1 - 1])
        b.fixes = [f for f in b.fixes if f[0] > self._t_sh]
        return job

    def _timed_round(self, job: dict) -> dict:
        import time

        t0 = time.process_time()
        res = run_round(job, job["specs"], self.lever, self.rate, self.config.min_speed_mps)
        res["cpu_s"] = time.process_time() - t0
        res["t"] = float(job["t"][-1])
        return res

    def poll(self, nav: Any = None) -> None:
        """Take a finished thread round."""
        if self._future is not None and self._future.done():
            res = self._future.result()
            self._future = None
            self._decide(res, nav)

    def close(self) -> None:
        """Wait for a running thread round and take it (no new search starts after it)."""
        if self._future is not None:
            self._future.result()
            self.poll(None)
        if self._executor is not None:
            self._executor.shutdown(wait=True)
            self._executor = None

    def __deepcopy__(self, memo: dict) -> MotionNoiseLearner:
        if self._future is not None or self._executor is not None:
            raise ModelError("a motion-noise learner with a worker thread cannot be copied (use worker='inline')")
        new = copy.copy(self)
        memo[id(self)] = new
        for k, v in self.__dict__.items():
            if k not in ("config", "lever"):
                setattr(new, k, copy.deepcopy(v, memo))
        return new

    # -- decisions ----------------------------------------------------------------------------------
    def _decide(self, res: dict, nav: Any) -> None:
        self.round_s.append(res["cpu_s"])
        # the drift counts rehearsed rounds only; the likelihood every round with fixes
        if not (res["rehearsed"] or self._lik) or self._shadows is None:
            return
        if res["rehearsed"]:
            self.n_rehearsals += 1
            self._all_scores.append(res["scores"])
        self._round += 1
        c = self.config
        if self._phase == "warm":
            if self._round >= c.warm_rounds:
                self._phase = "choose"
            return
        self._nis += res["nis"]
        self._scores.append(res["scores"])
        if self._lik:
            self._nll.append(res["nll"])
        n = len(self._scores)
        if self._phase == "choose" and n >= c.choose_rounds:
            (self._lik_after_choose if self._lik else self._after_choose)(res["t"], nav)
        elif self._phase == "confirm" and n >= c.confirm_rounds:
            (self._lik_after_confirm if self._lik else self._after_confirm)(res["t"], nav)

    def _nis_check(self, k: int) -> tuple[bool, list[dict]]:
        return decision.nis_ok(self._nis[k, 0::2], self._nis[k, 1::2], 3, self.config.nis_alpha)

    def _after_choose(self, t: float, nav: Any) -> None:
        c = self.config
        S = np.array(self._scores)
        d = S - S[:, [0]]
        if "previous" in self._roles:
            kp = self._roles.index("previous")
            v = decision.revert(d[:, kp], c.alpha, c.choose_rounds)
            if v.ok:
                self._log(t, "revert", switch=True, processes=describe(self.previous or ()),
                          from_processes=describe(self.spec), **v.evidence())
                self.spec, self.previous = self.previous or (), None
                self._restart(nav)
                return
        cand = [k for k, r in enumerate(self._roles) if r == "candidate"]
        allowed = [self._nis_check(k)[0] for k in cand]
        means = d.mean(axis=0)
        best = self._best_per_family(means, cand)
        j = decision.choose(d[:, cand], allowed)
        ranking = {str(k): {"processes": describe(self._specs[k]), "mean_log_ratio": float(means[k]),
                            "nis_inside": bool(a)} for k, a in zip(cand, allowed, strict=True)}
        self.families = refine(self.families, best)
        if j is None:
            self._log(t, "refuse", stage="choose", reason="no candidate drifts less than the current model inside "
                      "its NIS band", n_rounds=len(self._scores), candidates=ranking)
            self._restart(nav)
            return
        k = cand[j]
        self._chosen = k
        self._log(t, "choose", processes=describe(self._specs[k]), mean_log_ratio=float(means[k]),
                  n_rounds=len(self._scores), n_candidates=self._n_cands, candidates=ranking)
        # confirm on later rounds only: the current model's and the chosen candidate's shadows go on
        self._shadows = [e if i in (0, k) else None for i, e in enumerate(self._shadows)]
        self._scores = []
        self._nis = np.zeros_like(self._nis)
        self._phase = "confirm"

    def _after_confirm(self, t: float, nav: Any) -> None:
        c = self.config
        k = self._chosen
        assert k is not None
        S = np.array(self._scores)
        v = decision.confirm(S[:, k] - S[:, 0], self._n_cands, c.alpha, c.margin, c.confirm_rounds)
        nis_in, nis_info = self._nis_check(k)
        _, nis_cur = self._nis_check(0)
        ev = {**v.evidence(), "n_candidates": self._n_cands, "processes": describe(self._specs[k]),
              "nis_position": nis_info[0], "nis_velocity": nis_info[1], "nis_position_current": nis_cur[0]}
        if v.ok and nis_in:
            self._log(t, "confirm", switch=True, from_processes=describe(self.spec), **ev)
            self.previous, self.spec = self.spec, self._specs[k]
        else:
            self._log(t, "refuse", stage="confirm", **{**ev, "reason": v.reason or "NIS outside its band"})
        self._restart(nav)

    def _best_per_family(self, means: np.ndarray, cand: Sequence[int]) -> dict:
        """Per family the process of the candidate that changed only it with the lowest mean."""
        best: dict = {}
        for k in cand:
            new = [p for p in self._specs[k] if p not in self.spec]
            if len(new) != 1:
                continue
            p = new[0]
            if p.family not in best or means[k] < best[p.family][1]:
                best[p.family] = (p, means[k])
        return {f: p for f, (p, _) in best.items()}

    def _restart(self, nav: Any) -> None:
        """The next search starts at the next aided moving step (from the live filter, once it runs the
        current model)."""
        self._shadows = None
        self._stale = False
        self._reset_search()

    def _log(self, t_round: float, what: str, /, switch: bool = False, **kw: Any) -> None:
        self.history.append({"t_round": t_round, "decision": what, "switch": switch, "search": self.n_searches, **kw})
