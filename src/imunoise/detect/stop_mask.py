"""The stops of a whole drive that opens with a stop: λ_0 learned from the first ``static_duration`` seconds (a
stop, as the alignment assumes), then the static detector over the whole record
(docs/guide/theory.rst, 'Static detection').

The one place this rule lives: ``nav --zupt`` takes its ZUPT mask from the stops (``cli/nav.py``), and the in-use
noise takes its moving flag from them (:func:`imunoise.inuse.stops.moving_flag`); ``nav --zupt --imu-model`` with
an in-motion part detects once and derives both.
"""

from __future__ import annotations

import numpy as np

from imunoise.detect.config import DetectorConfig
from imunoise.detect.detector import detect_static
from imunoise.detect.results import Detection
from imunoise.detect.statistics import learn_lambda0

__all__ = ["detect_drive_stops"]


def detect_drive_stops(t: np.ndarray, accel: np.ndarray, gyro: np.ndarray, static_duration: float) -> Detection:
    """Static detection over a whole drive with λ_0 learned from its opening stop.

    Parameters
    ----------
    t : numpy.ndarray
        (n,) time [s], strictly increasing.
    accel, gyro : numpy.ndarray
        (n, 3) specific force [m/s²] and angular rate [rad/s], body axes (x, y horizontal).
    static_duration : float
        Length of the opening stop [s] λ_0 is learned from (:func:`~imunoise.detect.statistics.learn_lambda0`).

    Returns
    -------
    Detection
        The detection of :func:`~imunoise.detect.detector.detect_static`; ``config.lambda0`` is the learned λ_0.
    """
    t = np.asarray(t, dtype=float)
    accel = np.asarray(accel, dtype=float)
    lam = learn_lambda0(accel[t < t[0] + static_duration])
    return detect_static(t, accel, gyro, DetectorConfig(lambda0=lam))
