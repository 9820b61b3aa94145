"""Navigation: WGS84 Earth model, strapdown mechanization, loosely coupled EKF, alignment, metrics (SPEC §8).

The last stage of the data path (IMU → detection → modelling → filter): the filter takes IMU increments,
GNSS fixes, static/gate masks and one error model per sensor axis (anything with ``state_space(dt, freq)``).
It imports only the model algebra (:mod:`imunoise.model`, :mod:`imunoise.processes`) and
:mod:`imunoise.errors`; detection and identification are run by :mod:`imunoise.online` or the caller.
"""

from imunoise.nav.align import coarse_align
from imunoise.nav.defaults import EkfConfig, default_axis_models, load_axis_models
from imunoise.nav.ekf import InitialState, LooselyCoupledEKF, run_ekf
from imunoise.nav.metrics import nav_errors, summarize

__all__ = [
    "coarse_align", "EkfConfig", "default_axis_models", "load_axis_models", "InitialState",
    "LooselyCoupledEKF", "run_ekf", "nav_errors", "summarize",
]
