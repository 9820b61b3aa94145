"""Calibrate an IMU from the moving logs people already have: the offline twin of the online engine
(docs/guide/theory.rst, 'Static detection' and 'Online engine').

:func:`calibrate` takes one or more logs of the same IMU (:func:`read_log`: a ROS bag, a table with a column
mapping and units, a KF-GINS increment file or a dataset folder), finds the stops in each
(:func:`detect_stops`), pools the static segments per axis into one wavelet variance, identifies the model
(:func:`imunoise.noise.selection.select_model`, WVIC by default) and states what the stops can say. The package:
:mod:`~imunoise.calibrate.logs` (the logs and their speed sources), :mod:`~imunoise.calibrate.stops` (the stops of
one log), :mod:`~imunoise.calibrate.stream` (the same, streamed), :mod:`~imunoise.calibrate.result` (what the
horizon determines) and :mod:`~imunoise.calibrate.fit` (the pooled fit and :func:`calibrate`).
Built on the whole data path IMU → detection → modelling → filter (it uses the online engine's stop check), it
may import every stage below it.

Stops, per log (as the online engine does, with the same public pieces):

* λ_0 learned per log (:func:`imunoise.detect.learn_lambda0`, 2 × the median Eq. 9 statistic). The online
  engine learns it from the first seconds, which it assumes are a stop; a log picked from a drawer need not
  start still, so the default here learns it from the *quietest* ``learn_s`` seconds (the stretch with the
  smallest median statistic), which is the first stop when the log starts with one.
* the static detector (:func:`imunoise.detect.detect_static`: adaptive threshold, ``margin_s`` trimmed at both
  ends, ``min_duration_s``) run both ways on a whole log (:func:`imunoise.detect.both_ways.detect_static_both_ways`:
  forward ∩ time-reversed, so neither end carries the window's lag into a departure); a streamed log has the
  forward pass alone, each stop's end cut by :data:`~imunoise.calibrate.stops.STREAM_END_TRIM_S` more (the lag
  measured at departures); then the angular-rate gate: samples with ‖ω‖ > 30 °/s cut a segment (a turning
  vehicle is not at rest, whatever its accelerometers say).
* with a speed (a reference trajectory or GNSS), each segment goes through the online engine's stop check
  (:func:`imunoise.online.stop_verdict`) on its samples and ``stop_edge_s`` past either end
  (:func:`~imunoise.calibrate.stops.edge_verdict`): samples within ``stop_edge_s`` of one faster than
  ``OnlineConfig.stop_max_speed`` are dropped, so a stop ends before the departure reaches that speed.
* without a speed, a log with more than :data:`~imunoise.calibrate.stops.MAX_STOPS_PER_MIN` stops per minute
  (and at least 10) is refused in one line naming ``--gnss``/``--ref``: where the IMU is as quiet moving as at
  rest, steady cruising passes for stops and only a speed tells them apart
  (:func:`~imunoise.calibrate.stops.implausible_stops`).
* bias removed per segment (segment mean, docs/guide/theory.rst, 'Static detection'); no wavelet coefficient spans two
  segments (:class:`imunoise.noise.wv.WVAccumulator`).

The horizon. Pooled stops support scales up to the longest Haar scale τ_J with at least
:data:`imunoise.noise.wv.MIN_COEFFICIENTS` coefficients; in averaging time T_h = τ_J/(2f)
(:func:`imunoise.noise.equivalent_noise.default_horizon_s`). What that horizon determines, per axis
(:class:`AxisCalibration`):

* the white noise N (and QN, and Gauss–Markov terms with T_c ≤ T_h): values with CIs;
* the bias random walk K: a value only where the random walk rises above the white noise inside the horizon,
  i.e. the crossover averaging time T_x = √3·N/K (where N²/T = K²T/3) is ≤ T_h. Otherwise K is reported as a
  bound that holds for any model: K² ≤ 3·AV(T)/T at every T (the RW's Allan variance K²T/3 is part of the
  total, every other process adds to it), read on the upper limit of the WV's confidence band, K ≤
  min_j √(3·AV_hi(T_j)/T_j) (:func:`k_upper_bound`);
* a Gauss–Markov term with T_c > T_h, or a rate ramp: not determined (a slow AR1 and a random walk are two
  readings of the same rising curve on these scales); their effect is inside the K bound.

The exports (Kalibr, OpenVINS, ORB-SLAM3) follow the project's rules (:mod:`imunoise.export`): the (N, K) pair
matched over τ = update period .. horizon, K capped at the data's Allan bound, the τ range and the worst AV
ratio beside them. The dense Allan curve of the pooled stops is kept with each fit (``extra["data_allan"]``)
for that cap, as ``imunoise fit`` keeps that of its static record.
"""

from __future__ import annotations

from imunoise.calibrate.fit import MIN_STATIC_S, RATE_TOLERANCE, calibrate, pooled_fit
from imunoise.calibrate.logs import ACCEL_UNIT as ACCEL_UNIT
from imunoise.calibrate.logs import GYRO_UNIT as GYRO_UNIT
from imunoise.calibrate.logs import ImuLog, read_log
from imunoise.calibrate.result import K_CI_SPAN, AxisCalibration, CalibrationResult, k_upper_bound
from imunoise.calibrate.stops import LEARN_S, STILL_CONTRAST, LogStops, Stop, detect_stops, learn_lambda0_quietest
from imunoise.calibrate.stream import stream_stops

__all__ = [
    "MIN_STATIC_S",
    "LEARN_S",
    "STILL_CONTRAST",
    "RATE_TOLERANCE",
    "K_CI_SPAN",
    "ImuLog",
    "Stop",
    "LogStops",
    "AxisCalibration",
    "CalibrationResult",
    "read_log",
    "learn_lambda0_quietest",
    "detect_stops",
    "stream_stops",
    "k_upper_bound",
    "pooled_fit",
    "calibrate",
]
