"""Navigation: WGS84 Earth model, strapdown mechanization, loosely coupled EKF, alignment, metrics
(docs/guide/theory.rst, 'Navigation filter').

The last stage of the data path (IMU → detection → modelling → filter): the filter takes IMU increments,
GNSS fixes, static/gate masks and one error model per sensor axis (anything with ``state_space(dt, freq)``).
It imports only the model algebra (:mod:`imunoise.noise.model`, :mod:`imunoise.noise.processes`) and
:mod:`imunoise.errors`; detection and identification are run by :mod:`imunoise.online` or the caller.

Layout: :mod:`~imunoise.nav.state` names the filter's arrays; :mod:`~imunoise.nav.measurements` holds one
module per measurement (GNSS position and velocity, ZUPT/ZARU, non-holonomic constraints), each a (dz, H, R)
function; :mod:`~imunoise.nav.streams` carries the measurements of a run as typed streams;
:mod:`~imunoise.nav.filter_loop` is the filter engine, the one step sequence that :func:`~imunoise.nav.ekf.run_ekf`,
:class:`~imunoise.nav.step_filter.LooselyCoupledEKF`, the online engine and the noise schedule share.
"""

from imunoise.nav.aiding_sources import gnss_velocity_stream
from imunoise.nav.align import coarse_align
from imunoise.nav.defaults import EkfConfig, default_axis_models, load_axis_models
from imunoise.nav.ekf import InitialState, LooselyCoupledEKF, run_ekf
from imunoise.nav.measurements.gnss_velocity import GnssVelocity, as_gnss_velocity
from imunoise.nav.measurements.nhc import NhcConfig
from imunoise.nav.metrics import nav_errors, summarize

__all__ = [
    "coarse_align", "EkfConfig", "default_axis_models", "load_axis_models", "InitialState",
    "LooselyCoupledEKF", "run_ekf", "nav_errors", "summarize", "NhcConfig", "GnssVelocity", "as_gnss_velocity",
    "gnss_velocity_stream",
]
