"""The stop logic of the in-use noise: one moving flag for the estimate, ``nav`` and ``online``
(docs/guide/theory.rst, 'Static detection' and 'In-use noise')."""

from __future__ import annotations

import numpy as np

__all__ = ["moving_flag", "moving_of"]


def moving_of(stops) -> np.ndarray:
    """The moving flag per sample of a detection of the drive's stops
    (:func:`imunoise.detect.stop_mask.detect_drive_stops`): every sample that is not in a stop."""
    return ~np.asarray(stops.static, dtype=bool)


def moving_flag(imu, static_duration: float = 30.0) -> np.ndarray:
    """The moving flag per IMU sample: not a stop of the static detector (the one ``nav --zupt`` and the online
    engine use), λ0 learned from the first ``static_duration`` s of ``imu`` (a stop, as the alignment assumes;
    :func:`imunoise.detect.stop_mask.detect_drive_stops`). ``nav --imu-model``, ``online --imu-model`` and
    :func:`imunoise.inuse.estimate_in_motion` (for a drive without known stops) all take it from here (``nav
    --zupt`` with an in-motion part detects once and calls :func:`moving_of` on its detection)."""
    from imunoise.detect.stop_mask import detect_drive_stops

    gyro, accel = imu.rates()
    return moving_of(detect_drive_stops(imu.t, accel, gyro, static_duration))
