"""Two parts of :class:`~imunoise.online.navigator.OnlineNavigator` kept apart (mixins that read its state):
the ZUPT/ZARU step at a detected stop, and the views of the stop modeller."""

from __future__ import annotations

import math

import numpy as np

from imunoise.detect import StaticSegment
from imunoise.noise.estimator import GMWMFit
from imunoise.online.result import ModelUpdate

__all__ = ["ZuptStep", "ModellerViews"]


class ZuptStep:
    """Zero-velocity and zero-angular-rate updates while the detector says "static"
    (docs/guide/theory.rst, 'Navigation filter')."""

    def _zupt_step(self, t: float, gate: bool) -> None:
        """A ZUPT (and ZARU) every ``zupt_every`` samples of a static run of ``zupt_after`` or more, the gate
        closed and the filter slower than ``zupt_max_speed``."""
        cfg = self.config
        if self._static_run >= cfg.zupt_after and self._static_run % cfg.zupt_every == 0 \
                and not gate and self.ekf.view.speed_h < cfg.zupt_max_speed:
            # the χ² test of the zero-velocity pseudo-measurement (NIS = vᵀ(P_vv + σ²I)⁻¹v ≤ zupt_chi2, 3 dof;
            # 0 = off): a detector false positive on a moving car (a noisy IMU's learned λ0 lets smooth
            # cruising pass Eq. 9) would otherwise be forced into the filter
            if self.ekf.zupt_update(cfg.zupt_sigma_v, chi2=cfg.zupt_chi2):
                self.ekf.zaru_update(self._zaru_sigma())
            elif not self._zupt_rejected:
                self._zupt_rejected = True
                self._event("zupt_rejected", t, speed_mps=float(np.linalg.norm(self.ekf.view.vel)))

    def _zaru_sigma(self) -> float:
        """σ of one ZARU sample: the larger of the configured σ, the current gyro model's per-sample white σ
        and the gyro scatter measured over this stop so far (the update uses a single increment, whose noise
        on a vibrating car is the vibration, not the datasheet's)."""
        s = self.config.zaru_sigma_w
        for m, _ in self.current_models[:3]:
            s = max(s, math.sqrt(m.white_variance()))
        n = min(self._static_run, 200, len(self._rows))
        if n >= 10:
            g = np.array(self._rows[-n:])[:, :3]
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
