"""Two parts of :class:`~imunoise.online.navigator.OnlineNavigator` kept apart: the ZUPT/ZARU step at a detected
stop (a collaborator handed the engine state) and the views of the stop modeller (a mixin reading its
``modeller``)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from imunoise.detect import StaticSegment
from imunoise.nav.zupt_policy import zupt_due_at
from imunoise.noise.estimator import GMWMFit
from imunoise.noise.model import Model
from imunoise.online.engine_state import EngineState
from imunoise.online.result import ModelUpdate

__all__ = ["Zupt", "ModellerViews"]


class Zupt:
    """Zero-velocity and zero-angular-rate updates while the detector says "static"
    (docs/guide/theory.rst, 'Navigation filter').

    Reads ``state.static_run`` and ``state.rows``, writes ``state.zupt_rejected`` and the ``zupt_rejected``
    event."""

    def __init__(self, config: Any, state: EngineState):
        self.config = config
        self.state = state

    def step(self, t: float, gate: bool, ekf: Any, models: Sequence[Model]) -> None:
        """A ZUPT (and ZARU) where the one rule says it is due (:func:`~imunoise.nav.zupt_policy.zupt_due_at`:
        every ``zupt_every`` samples of a static run of ``zupt_after`` or more, the gate closed) and the filter is
        slower than ``zupt_max_speed``; ``models``: the filter's current axis models."""
        cfg = self.config
        st = self.state
        if zupt_due_at(st.static_run, cfg.zupt_every, cfg.zupt_after, gate) and ekf.view.speed_h < cfg.zupt_max_speed:
            # the χ² test of the zero-velocity pseudo-measurement (NIS = vᵀ(P_vv + σ²I)⁻¹v ≤ zupt_chi2, 3 dof;
            # 0 = off): a detector false positive on a moving car (a noisy IMU's learned λ0 lets smooth
            # cruising pass Eq. 9) would otherwise be forced into the filter
            if ekf.zupt_update(cfg.zupt_sigma_v, chi2=cfg.zupt_chi2):
                ekf.zaru_update(self.zaru_sigma(models))
            elif not st.zupt_rejected:
                st.zupt_rejected = True
                st.event("zupt_rejected", t, speed_mps=float(np.linalg.norm(ekf.view.vel)))

    def zaru_sigma(self, models: Sequence[Model]) -> float:
        """σ of one ZARU sample: the larger of the configured σ, the current gyro model's per-sample white σ
        and the gyro scatter measured over this stop so far (the update uses a single increment, whose noise
        on a vibrating car is the vibration, not the datasheet's)."""
        s = self.config.zaru_sigma_w
        for m in models[:3]:
            s = max(s, math.sqrt(m.white_variance()))
        rows = self.state.rows
        n = min(self.state.static_run, 200, len(rows))
        if n >= 10:
            g = np.array(rows[-n:])[:, :3]
            s = max(s, float(np.max(np.std(g, axis=0))))
        return s


class ModellerViews:
    """What the navigator's :class:`~imunoise.online.modeller.StopModeller` holds, as navigator attributes."""

    @property
    def fits(self) -> list[GMWMFit | None]:
        """The modeller's current fit per axis (gyro x, y, z, accel x, y, z; None before identification)."""
        return self.modeller.fits

    @property
    def updates(self) -> list[ModelUpdate]:
        """Every modelling job's outcome so far (:attr:`StopModeller.updates`)."""
        return self.modeller.updates

    @property
    def segments(self) -> list[StaticSegment]:
        """The stops pooled so far (after the stop guard)."""
        return self.modeller.segments

    @property
    def static_s(self) -> float:
        """Static data pooled so far [s], the earlier drives' included."""
        return self.modeller.static_s

    def static_pieces(self) -> list[np.ndarray]:
        """Every static piece pooled so far (:meth:`StopModeller.static_pieces`): the ``earlier_static`` of the
        next drive of the same IMU."""
        return self.modeller.static_pieces()
