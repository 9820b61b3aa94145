"""The stop logic of the in-use noise: one moving flag for the estimate, ``nav`` and ``online``
(docs/guide/theory.rst, 'Static detection' and 'In-use noise')."""

from __future__ import annotations

import numpy as np

__all__ = ["moving_flag"]


def moving_flag(imu, static_duration: float = 30.0) -> np.ndarray:
    """The moving flag per IMU sample: not a stop of the static detector (the one ``nav --zupt`` and the online
    engine use), λ0 learned from the first ``static_duration`` s of ``imu`` (a stop, as the alignment assumes).
    ``nav --imu-model``, ``online --imu-model`` and :func:`imunoise.inuse.estimate_in_motion` (for a drive
    without known stops) all take it from here."""
    from imunoise.detect import DetectorConfig, detect_static, learn_lambda0

    gyro, accel = imu.rates()
    t = np.asarray(imu.t, dtype=float)
    lam = learn_lambda0(accel[t < t[0] + static_duration])
    return ~np.asarray(detect_static(t, accel, gyro, DetectorConfig(lambda0=lam)).static, dtype=bool)
