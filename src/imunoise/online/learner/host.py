"""The navigator's side of the learner: a collaborator of :class:`~imunoise.online.navigator.OnlineNavigator`.

It builds the learner, hands it every filter step, swaps the learned model into the live filter when a
decision switches it, adds the departure-step variance to the live filter at every start from a stop while
the learned model has a step, and writes the events:

* ``motion_noise_start`` (the first search's shadows start; ``shadows``);
* ``motion_noise_choose`` / ``motion_noise_confirm`` / ``motion_noise_refuse`` / ``motion_noise_revert``: every
  decision with its evidence (mean paired log ratio, t, p, the level α/m, the rounds, the NIS of position and
  velocity against their bands, the candidates' means on the choose rounds);
* ``motion_noise`` after a switch (confirm or revert): the processes the live filter now runs (``processes``,
  ``sigma_dph``/``tc_s`` of the gyro Gauss–Markov per axis) and the swap's kept/reset states;
* ``motion_noise_end``: the learned processes, the counts, the cost (``elapsed_s``: CPU seconds of the median round
  and of all rounds) and ``evidence`` (the prior of the next drive, :class:`MotionNoisePrior`).
"""

from __future__ import annotations

from typing import Any

from imunoise.online.engine_state import EngineState
from imunoise.online.learner.core import MotionNoiseLearner
from imunoise.online.learner.rehearsal import add_departure

__all__ = ["LearnerHost"]


class LearnerHost:
    """The navigator's side of the learner (module docstring): ``motion``, the learner (None when
    ``config.motion_noise`` is None), and ``fixes``, the fixes the live filter used since its last observation.
    Writes the learner's events to ``state``; swaps the learned model into the navigator's filter (its ``ekf``,
    ``static_models`` and ``current_models``)."""

    def __init__(self, config: Any, state: EngineState, rate: float):
        self.config = config
        self.state = state
        self.rate = rate
        cfg = config.motion_noise
        self.motion = (MotionNoiseLearner(cfg, rate, config.ekf.lever_arm, worker=config.worker)
                       if cfg is not None else None)
        self.fixes: list[tuple] = []

    def first_models(self, models: Any, static_models: Any) -> Any:
        """The filter's first models: ``models``, or with a carried prior its processes added to the
        ``static_models`` from the first sample."""
        if self.motion is not None and self.config.motion_noise.prior is not None:
            return self.motion.compose(static_models)
        return models

    def fix_used(self, fix: tuple) -> None:
        """The live filter applied ``fix``."""
        if self.motion is not None:
            self.fixes.append(fix)

    def departure_due(self, prev_run: int, is_static: bool) -> bool:
        """Whether this sample is a start from a stop at which the learned model adds a departure step."""
        m = self.motion
        return m is not None and not is_static and prev_run >= m.min_stop_n and m.departure_var() is not None

    def step(self, nav: Any, t: float, dth: Any, dvv: Any, is_static: bool, prev_run: int) -> None:
        """After the filter step and its fixes at ``t``: the departure step, then the learner's observation."""
        m = self.motion
        if self.departure_due(prev_run, is_static):
            add_departure(nav.ekf, m.departure_var())
        fixes, self.fixes = self.fixes, []
        n_hist = len(m.history)
        m.observe(nav, t, dth, dvv, is_static, fixes)
        self._motion_events(nav, t, n_hist)

    def _motion_events(self, nav: Any, t: float, n_hist: int) -> None:
        """Log the learner's start and its decisions since ``n_hist``; swap in a switched model."""
        m = self.motion
        ev = self.state.event
        if m.t_start == t and m.n_starts == 1 and not any(e["event"] == "motion_noise_start"
                                                          for e in self.state.events):
            ev("motion_noise_start", t, shadows=len(m.cands))
        for h in m.history[n_hist:]:
            ev(f"motion_noise_{h['decision']}", t, **{k: v for k, v in h.items() if k != "decision"})
            if h["switch"]:
                models = m.compose(nav.static_models)
                counts = nav.ekf.swap_model(models, preserve=True, imu_rate_hz=self.rate)
                nav.current_models = models
                s = m.summary()
                ev("motion_noise", t, processes=s["processes"], sigma_dph=s["sigma_dph"], tc_s=s["tc_s"],
                   n_rehearsals=m.n_rehearsals, n_prior=m.n_prior, **counts)

    def poll(self, nav: Any, t: float) -> None:
        """The thread worker: collect a finished round."""
        if self.motion is not None and self.config.worker == "thread":
            n_hist = len(self.motion.history)
            self.motion.poll(nav)
            self._motion_events(nav, t, n_hist)

    def finish(self, nav: Any) -> None:
        """Close the learner at the end of the stream (its last decisions and the ``motion_noise_end`` event)."""
        m = self.motion
        if m is None:
            return
        t = self.state.t_last
        n_hist = len(m.history)
        m.close()
        self._motion_events(nav, t, n_hist)
        self.state.event("motion_noise_end", t, **m.summary(), evidence=m.evidence().to_dict())
