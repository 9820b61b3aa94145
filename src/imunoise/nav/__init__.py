"""Navigation: WGS84 Earth model, strapdown mechanization, loosely coupled EKF, alignment, metrics (SPEC §8)."""

from imunoise.nav.align import coarse_align
from imunoise.nav.defaults import EkfConfig, default_axis_models, load_axis_models
from imunoise.nav.ekf import InitialState, LooselyCoupledEKF, run_ekf
from imunoise.nav.metrics import nav_errors, summarize

__all__ = [
    "coarse_align", "EkfConfig", "default_axis_models", "load_axis_models", "InitialState",
    "LooselyCoupledEKF", "run_ekf", "nav_errors", "summarize",
]
