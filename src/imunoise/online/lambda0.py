"""The navigator's detector feed (docs/guide/theory.rst, 'Static detection'): the static detector with a fixed λ_0 from
the configuration, or one
learned from the first ``learn_lambda0_s`` seconds (samples held until then, then replayed through the
detector)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from imunoise.detect import DetectorConfig, StaticDetector, learn_lambda0
from imunoise.errors import ImunoiseError
from imunoise.online.engine_state import EngineState

__all__ = ["DetectorFeed"]

Sample = Callable[..., None]
"""The navigator's per-sample path: ``sample(t, dth, dvv, gyro, accel, is_static, gate_open, segments)``."""


class DetectorFeed:
    """The static detector of the online engine and the learning of its λ_0.

    Writes ``state.stop_start_n`` (when the detector is made) and the ``lambda0`` event; holds the samples pushed
    while λ_0 is learned (``pending``, from ``learn_t0`` on) and hands each sample with the detector's verdict to
    the navigator's per-sample path."""

    def __init__(self, state: EngineState, rate: float, learn_s: float, config: DetectorConfig | None):
        self.state = state
        self.rate = rate
        self.learn_s = learn_s
        self.detector: StaticDetector | None = None
        self.lambda0: float | None = None
        self.pending: list[tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        self.learn_t0: float | None = None
        if config is not None:
            self.make_detector(config)

    def make_detector(self, cfg: DetectorConfig) -> None:
        """The detector with ``cfg`` (its λ_0 fixed)."""
        self.detector = StaticDetector(cfg, self.rate)
        self.lambda0 = float(cfg.lambda0)
        self.state.stop_start_n = int(math.ceil((cfg.min_duration_s + 2 * cfg.margin_s) * self.rate)) + 1

    def push(self, t, dth, dvv, gyro, accel, sample: Sample) -> None:
        """One increment: to the detector and on to ``sample``, or held while λ_0 is learned."""
        if self.detector is not None:
            self._detect(t, dth, dvv, gyro, accel, sample)
            return
        if self.learn_t0 is None:
            self.learn_t0 = t
        if t < self.learn_t0 + self.learn_s:
            self.pending.append((t, dth, dvv, gyro, accel))
            return
        self.finish_learning(sample)
        self._detect(t, dth, dvv, gyro, accel, sample)

    def _detect(self, t, dth, dvv, gyro, accel, sample: Sample) -> None:
        segs = self.detector.push(t, accel, gyro)
        sample(t, dth, dvv, gyro, accel, self.detector.is_static, self.detector.gate_open, segs)

    def take_pending(self) -> list[tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """The held samples, handed over (the feed holds none after)."""
        held, self.pending = self.pending, []
        return held

    def finish_learning(self, sample: Sample) -> None:
        """λ_0 from the held samples, then each held sample through the detector to ``sample``."""
        held = self.take_pending()
        acc = np.array([s[4] for s in held]) if held else np.zeros((0, 3))
        self.learn_from(acc, self.learn_t0 if self.learn_t0 is not None else 0.0)
        for s in held:
            self._detect(*s, sample)

    def learn_from(self, accel_static: np.ndarray, t0: float) -> None:
        """Learn λ_0 from specific forces (n, 3) [m/s²] starting at ``t0`` [s] and make the detector with it (the
        default λ_0 when it cannot be learned; the ``lambda0`` event says which)."""
        base = DetectorConfig()
        try:
            lam = learn_lambda0(accel_static, window=base.window)
            src = f"learned from the first {self.learn_s:g} s"
        except ImunoiseError as exc:
            lam = base.lambda0
            src = f"default (could not learn: {exc})"
        self.make_detector(replace(base, lambda0=lam))
        self.state.event("lambda0", t0, lambda0=lam, source=src)
