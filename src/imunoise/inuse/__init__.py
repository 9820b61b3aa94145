"""In-use noise: the noise the filter sees while the vehicle moves, estimated from whole GNSS-aided drives and
carried in the model file (docs/guide/theory.rst, 'In-use noise'). It sits on the filter end of the data path
IMU → detection → modelling → filter: it runs the aided filter over whole drives and may import every stage below.

* :class:`InMotionPart` (with :class:`AxisInMotion`, :class:`BiasWander`, :class:`Interval`, :class:`Bound`):
  the model file's ``in_motion`` part (:mod:`imunoise.noise.in_motion`);
* :func:`estimate_in_motion`: maximum likelihood of the GNSS innovations over whole drives
  (:mod:`imunoise.inuse.estimate`), returning an :class:`InMotionEstimate`; its search is finished by Newton
  steps and its intervals come from the observed information (:mod:`imunoise.inuse.information`), widened by the
  model family's error through the fixes' dispersion (:mod:`imunoise.inuse.dispersion`);
* :func:`summary_lines`: the per-axis factors with intervals and units, as ``calibrate`` prints them.
"""

from imunoise.inuse.estimate import InMotionEstimate, estimate_in_motion, static_models, static_nk
from imunoise.inuse.summary import summary_lines
from imunoise.noise.in_motion import AxisInMotion, BiasWander, Bound, InMotionPart, Interval, gm_equivalent_k

__all__ = ["AxisInMotion", "BiasWander", "Bound", "InMotionEstimate", "InMotionPart", "Interval",
           "estimate_in_motion", "gm_equivalent_k", "static_models", "static_nk", "summary_lines"]


def __getattr__(name: str):
    # the old name of static_models (imunoise.inuse.estimate warns and hands it over)
    if name == "static_pairs":
        from imunoise.inuse import estimate

        return estimate.__getattr__(name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
