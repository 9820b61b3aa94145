"""The navigator's detector threshold λ_0 (docs/guide/theory.rst, 'Static detection'): a fixed one from the
configuration, or one learned from
the first ``learn_lambda0_s`` seconds (samples held until then, then replayed through the detector)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from imunoise.detect import DetectorConfig, StaticDetector, learn_lambda0
from imunoise.errors import ImunoiseError

__all__ = ["Lambda0Learning"]


class Lambda0Learning:
    """Detector construction and λ_0 learning; a mixin of :class:`~imunoise.online.navigator.OnlineNavigator`,
    whose state it reads."""

    def _make_detector(self, cfg: DetectorConfig) -> None:
        self.detector = StaticDetector(cfg, self.rate)
        self.lambda0 = float(cfg.lambda0)
        self._stop_start_n = int(math.ceil((cfg.min_duration_s + 2 * cfg.margin_s) * self.rate)) + 1

    def _learn_push(self, t, dth, dvv, gyro, accel) -> None:
        if self._learn_t0 is None:
            self._learn_t0 = t
        if t < self._learn_t0 + self.config.learn_lambda0_s:
            self._pending_samples.append((t, dth, dvv, gyro, accel))
            return
        self._learn_finish()
        self._after_learning(t, dth, dvv, gyro, accel)

    def _after_learning(self, t, dth, dvv, gyro, accel) -> None:
        segs = self.detector.push(t, accel, gyro)
        self._sample(t, dth, dvv, gyro, accel, self.detector.is_static, self.detector.gate_open, segs)

    def _learn_finish(self) -> None:
        held = self._pending_samples
        self._pending_samples = []
        acc = np.array([s[4] for s in held]) if held else np.zeros((0, 3))
        self._learn_from(acc, self._learn_t0 if self._learn_t0 is not None else 0.0)
        for s in held:
            self._after_learning(*s)

    def _learn_from(self, accel_static: np.ndarray, t0: float) -> None:
        base = DetectorConfig()
        try:
            lam = learn_lambda0(accel_static, window=base.window)
            src = f"learned from the first {self.config.learn_lambda0_s:g} s"
        except ImunoiseError as exc:
            lam = base.lambda0
            src = f"default (could not learn: {exc})"
        self._make_detector(replace(base, lambda0=lam))
        self._event("lambda0", t0, lambda0=lam, source=src)
