"""Static (zero-motion) detection (docs/guide/theory.rst, 'Static detection', paper §2.3): Eq. 9 moving std, adaptive
threshold, segments, gate.

``kernels``: the numba kernel (one pass over a chunk, state carried between calls). ``detector``: the
streaming :class:`StaticDetector` (the only detector implementation) and :func:`detect_static` (that detector
fed a whole record in chunks); ``both_ways``: :func:`~imunoise.detect.both_ways.detect_static_both_ways`, a whole
record detected forward and time-reversed (no window lag at either end of a stop).
``stop_mask``: :func:`~imunoise.detect.stop_mask.detect_drive_stops`, the stops of a drive that opens with a stop
(λ_0 learned there). ``config``: :class:`DetectorConfig`. ``statistics``: Eq. 9 moving std, the
Eq. 10 threshold, the gate and :func:`learn_lambda0`. ``results``: segments and detections. ``metrics``:
scoring a mask against the truth. Every public name is importable from ``imunoise.detect`` (and from
``imunoise.detect.detector``).

The second stage of the data path (IMU → detection → modelling → filter): it takes SI arrays, imports
only :mod:`imunoise.errors`, and its segments and masks feed the modelling and the filter's ZUPT/gate.
"""

from __future__ import annotations

from imunoise.detect import detector
from imunoise.detect.detector import *  # noqa: F403 - the public names, listed once: in detector.__all__

__all__ = list(detector.__all__)
