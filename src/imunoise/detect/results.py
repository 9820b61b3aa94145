"""What the static detector returns: segments, the per-epoch detection and a chunk's part of it, and
the samples inside the segments (docs/guide/theory.rst, 'Static detection')."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from imunoise.detect.config import DetectorConfig
from imunoise.errors import DataError

__all__ = ["ChunkDetection", "Detection", "StaticSegment", "segment_data"]


@dataclass(frozen=True)
class StaticSegment:
    """A detected static segment: samples ``i0 ≤ i < i1`` (slice convention, ``data[i0:i1]``);
    ``t0`` = t[i0] and ``t1`` = t[i1 − 1] are the times of its first and last sample [s]."""

    t0: float
    t1: float
    i0: int
    i1: int

    @property
    def duration(self) -> float:
        """t1 − t0 [s]."""
        return self.t1 - self.t0

    @property
    def slice(self) -> slice:
        return slice(self.i0, self.i1)


@dataclass(frozen=True, eq=False)
class Detection:
    """Result of :func:`detect_static`. Arrays are per epoch (n samples).

    ``statistic`` (n, 2) T of Eq. (9) for accel x, y [m/s²] (NaN while the window fills);
    ``threshold`` (n,) λ_i [m/s²]; ``static_raw`` the per-epoch test; ``static`` epochs inside the
    kept (trimmed, long enough) ``segments``; ``gate_open`` ‖ω‖ > gate_rate.
    """

    t: np.ndarray
    statistic: np.ndarray
    threshold: np.ndarray
    static_raw: np.ndarray
    static: np.ndarray
    segments: list[StaticSegment]
    gate_open: np.ndarray
    config: DetectorConfig = field(default_factory=DetectorConfig)

    @property
    def static_time_s(self) -> float:
        """Total duration of the kept segments [s]."""
        return float(sum(s.duration for s in self.segments))


@dataclass(frozen=True, eq=False)
class ChunkDetection:
    """Per-epoch results of one :meth:`StaticDetector.push_chunk` call (fields as in :class:`Detection`)
    and the segments completed inside the chunk. ``completed_at[j]`` is the index (counted from the
    detector's first sample) of the sample whose :meth:`StaticDetector.push` would have returned
    ``segments[j]``: the first non-static sample after its run."""

    statistic: np.ndarray
    threshold: np.ndarray
    static_raw: np.ndarray
    gate_open: np.ndarray
    segments: list[StaticSegment]
    completed_at: list[int] = field(default_factory=list)


def segment_data(detection: Detection, data: np.ndarray, remove_bias: bool = True) -> list[np.ndarray]:
    """Samples of ``data`` (n, k) inside each static segment, each minus its segment mean when
    ``remove_bias`` (docs/guide/theory.rst, 'Static detection': the bias of a stop is removed before the GMWM)."""
    data = np.asarray(data, dtype=float)
    if data.shape[0] != detection.t.size:
        raise DataError(
            f"segment_data: data has {data.shape[0]} rows, the detection has {detection.t.size} epochs"
        )
    out = []
    for s in detection.segments:
        d = data[s.i0 : s.i1]
        out.append(d - d.mean(axis=0) if remove_bias else d.copy())
    return out

