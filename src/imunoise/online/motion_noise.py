"""In-motion noise learned while driving (``gmwm_dyn``): the names of :mod:`imunoise.online.learner`.

The learner lives in the package :mod:`imunoise.online.learner` (candidates, rehearsal, decision rule, state,
navigator glue); this module keeps the import path of earlier releases.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from imunoise.online.learner import (
    MotionNoiseConfig,
    MotionNoiseLearner,
    MotionNoisePrior,
    horizontal_distance,
    ned_offset,
)
from imunoise.online.learner.candidates import DPH, LearnedProcess, compose, rated

__all__ = ["MotionNoiseConfig", "MotionNoisePrior", "MotionNoiseLearner", "add_motion_gm", "ned_offset",
           "horizontal_distance"]


def add_motion_gm(models: Sequence[Any], spec: Sequence[tuple[float, float]], rate_hz: float) -> list:
    """The six models (each carrying its rate) with a Gauss–Markov process of σ ``spec[j][0]`` [°/h] and
    correlation time ``spec[j][1]`` [s] added to gyro axis j (σ = 0 adds nothing); accelerometer axes unchanged."""
    out = list(models)
    for j, (sg, tc) in enumerate(spec):
        if sg > 0 and math.isfinite(sg):
            one = compose([out[j]], (LearnedProcess("gm", "gyro", float(sg) * DPH, float(tc)),), rate_hz)[0]
            out[j] = one
    return [rated(m, rate_hz) for m in out]
