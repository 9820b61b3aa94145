"""Offline static detection both ways: the streaming detector run forward and on the time-reversed record,
a sample static when both call it static (:func:`detect_static_both_ways`).

Why. The Eq. 9 statistic is the std of the *last* N samples, so forward in time a run of static epochs starts
N samples after the motion stops (late, harmless: the stop's first samples are lost) and ends when the
departure's motion has grown enough to lift the window's std above λ — late, harmful: a jerk-limited start
(the vehicle creeps, the specific force rises over a second or more) stays under λ for up to several
seconds, and those seconds of motion enter the stop. The ``margin_s`` trim removes 0.5 s at either end
whatever the lag. Run on the reversed record the same window looks at the *next* N samples: its runs end
before the departure (the window sees it coming) and start late at the arrival of the stop in reversed time,
i.e. early in forward time. The intersection starts with the forward pass (after the braking) and ends with
the reversed one (before the departure): neither end carries the window's lag. Measured on simulated
drives (``scripts/calibrate_sim_drives.py``, docs/evidence/calibrate_stops.md): 0 s of motion kept.

It needs the samples after a stop, so it is for whole records (``imunoise calibrate``); the streaming
:class:`imunoise.detect.StaticDetector` (and the online engine) keep the forward pass alone.
"""

from __future__ import annotations

import numpy as np

from imunoise.detect.config import DetectorConfig
from imunoise.detect.detector import detect_static
from imunoise.detect.results import Detection, StaticSegment

__all__ = ["detect_static_both_ways", "segments_of_mask"]


def segments_of_mask(t: np.ndarray, mask: np.ndarray, min_duration_s: float) -> list[StaticSegment]:
    """The runs of ``mask`` lasting ≥ ``min_duration_s`` (t[last] − t[first]) as segments."""
    e = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    out = []
    for a, b in zip(e[::2].tolist(), e[1::2].tolist(), strict=True):
        if t[b - 1] - t[a] >= min_duration_s:
            out.append(StaticSegment(float(t[a]), float(t[b - 1]), a, b))
    return out


def detect_static_both_ways(
    t: np.ndarray,
    accel: np.ndarray,
    gyro: np.ndarray,
    config: DetectorConfig = DetectorConfig(),  # noqa: B008 (frozen, immutable)
    rate_hz: float | None = None,
) -> Detection:
    """Static detection of a whole record forward and time-reversed (module docstring).

    Each pass is :func:`imunoise.detect.detect_static` with ``config`` (adaptive threshold, ``margin_s`` trimmed,
    ``min_duration_s``); a sample is static when it lies in a segment of both; the segments are the runs of
    that mask lasting ≥ ``min_duration_s``.

    Parameters
    ----------
    t, accel, gyro, config, rate_hz
        As for :func:`imunoise.detect.detect_static`.

    Returns
    -------
    Detection
        The forward pass's statistic and threshold; ``static_raw`` the per-epoch test of both passes (AND),
        ``static`` and ``segments`` of the intersection, ``gate_open`` (per sample, the same both ways).
    """
    fwd = detect_static(t, accel, gyro, config, rate_hz=rate_hz)
    t_arr = fwd.t
    rev = detect_static(-t_arr[::-1], np.asarray(accel, dtype=float)[::-1], np.asarray(gyro, dtype=float)[::-1],
                        config, rate_hz=rate_hz)
    static = fwd.static & rev.static[::-1]
    segments = segments_of_mask(t_arr, static, config.min_duration_s)
    kept = np.zeros(t_arr.size, dtype=bool)
    for s in segments:
        kept[s.i0 : s.i1] = True
    return Detection(t=t_arr, statistic=fwd.statistic, threshold=fwd.threshold,
                     static_raw=fwd.static_raw & rev.static_raw[::-1], static=kept, segments=segments,
                     gate_open=fwd.gate_open, config=config)
