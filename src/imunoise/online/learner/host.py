"""The navigator's side of the learner: a mixin of :class:`~imunoise.online.navigator.OnlineNavigator`.

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

from imunoise.online.learner.core import MotionNoiseLearner
from imunoise.online.learner.rehearsal import add_departure

__all__ = ["LearnerHost"]


class LearnerHost:
    """Learner glue of the navigator (module docstring); reads and writes the navigator's state."""

    _motion: MotionNoiseLearner | None

    def _learner_init(self, models: Any) -> Any:
        """Make the learner (``config.motion_noise``); returns the filter's first models (a carried prior's
        processes from the first sample)."""
        cfg = self.config.motion_noise
        self._motion = (MotionNoiseLearner(cfg, self.rate, self.config.ekf.lever_arm, worker=self.config.worker)
                        if cfg is not None else None)
        self._motion_fixes: list[tuple] = []
        if self._motion is not None and cfg.prior is not None:
            models = self._motion.compose(self.static_models)
        return models

    def departure_due(self, prev_run: int, is_static: bool) -> bool:
        """Whether this sample is a start from a stop at which the learned model adds a departure step."""
        m = self._motion
        return m is not None and not is_static and prev_run >= m.min_stop_n and m.departure_var() is not None

    def _learner_step(self, t: float, dth: Any, dvv: Any, is_static: bool, prev_run: int) -> None:
        """After the filter step and its fixes at ``t``: the departure step, then the learner's observation."""
        m = self._motion
        if self.departure_due(prev_run, is_static):
            add_departure(self.ekf, m.departure_var())
        fixes, self._motion_fixes = self._motion_fixes, []
        n_hist = len(m.history)
        m.observe(self, t, dth, dvv, is_static, fixes)
        self._motion_events(t, n_hist)

    def _motion_events(self, t: float, n_hist: int) -> None:
        """Log the learner's start and its decisions since ``n_hist``; swap in a switched model."""
        m = self._motion
        if m.t_start == t and m.n_starts == 1 and not any(e["event"] == "motion_noise_start" for e in self.events):
            self._event("motion_noise_start", t, shadows=len(m._specs))
        for h in m.history[n_hist:]:
            self._event(f"motion_noise_{h['decision']}", t, **{k: v for k, v in h.items() if k != "decision"})
            if h["switch"]:
                models = m.compose(self.static_models)
                counts = self.ekf.swap_model(models, preserve=True, imu_rate_hz=self.rate)
                self.current_models = models
                s = m.summary()
                self._event("motion_noise", t, processes=s["processes"], sigma_dph=s["sigma_dph"], tc_s=s["tc_s"],
                            n_rehearsals=m.n_rehearsals, n_prior=m.n_prior, **counts)

    def _learner_poll(self, t: float) -> None:
        if self._motion is not None and self.config.worker == "thread":
            n_hist = len(self._motion.history)
            self._motion.poll(self)
            self._motion_events(t, n_hist)

    def _learner_finish(self) -> None:
        m = self._motion
        if m is None:
            return
        n_hist = len(m.history)
        m.close()
        self._motion_events(self._t_last, n_hist)
        self._event("motion_noise_end", self._t_last, **m.summary(), evidence=m.evidence().to_dict())
