"""Online GMWM INS/GNSS engine (docs/guide/theory.rst, 'System overview' and 'Online engine'; paper Fig. 1): static
detection → online GMWM → model hot-swap in
the EKF. The last stage of the data path IMU → detection → modelling → filter: it drives the detector, the
estimators and the filter, and imports from all three, never the other way. One concept per module, every public
name importable from ``imunoise.online``:

``config``
    :class:`OnlineConfig` (the engine's settings), ``COMPLETE``, ``NEGLIGIBLE``, :func:`config_summary`.
``to_filter``
    The engine's settings on the one fit → filter-noise mapping (:mod:`imunoise.nav.filter_model`):
    :func:`ekf_axis_model` (one axis), :func:`filter_axis_models` (six axes), :func:`data_horizon`,
    :func:`dr_equivalent_rw`.
``jobs``
    The modelling job (:func:`model_job`: identification or refit per axis, plausibility check), a pure
    function run inline or in a worker thread.
``modeller``
    :class:`StopModeller`: the static data pooled from the stops, the per-axis fits, the modelling jobs (inline
    or on the worker thread) and the updates waiting for their effect time; the navigator asks it which are due.
``result``
    :class:`ModelUpdate`, :class:`OnlineResult`, the per-epoch :class:`EpochStore` and :func:`log_event` (one
    entry of the run's event log).
``stops``
    Which detected stops are modelled: :func:`stop_verdict` (the navigation check of a static segment,
    ``OnlineConfig.stop_guard``) and its :class:`StopVerdict`.
``motion_noise``
    In-motion gyro noise learned while driving (``OnlineConfig.motion_noise``): :class:`MotionNoiseConfig`,
    :class:`MotionNoiseLearner` (shadow filters that rehearse GNSS outages on the data seen),
    :func:`add_motion_gm`, :func:`ned_offset`, :func:`horizontal_distance`.
``navigator``
    :class:`OnlineNavigator` (streaming and batch; the engine, its docstring explains the modelling, the
    mapping, the swap and the worker with the measurements behind them) and :func:`run_online`.
"""

from __future__ import annotations

from imunoise.online.config import COMPLETE, NEGLIGIBLE, OnlineConfig, config_summary
from imunoise.online.jobs import model_job
from imunoise.online.modeller import StopModeller
from imunoise.online.motion_noise import (
    MotionNoiseConfig,
    MotionNoiseLearner,
    MotionNoisePrior,
    add_motion_gm,
    horizontal_distance,
    ned_offset,
)
from imunoise.online.navigator import OnlineNavigator, run_online
from imunoise.online.result import EpochStore, ModelUpdate, OnlineResult, log_event
from imunoise.online.stops import StopVerdict, stop_verdict
from imunoise.online.to_filter import data_horizon, dr_equivalent_rw, ekf_axis_model, filter_axis_models

__all__ = [
    "OnlineConfig",
    "OnlineNavigator",
    "OnlineResult",
    "ModelUpdate",
    "ekf_axis_model",
    "filter_axis_models",
    "dr_equivalent_rw",
    "data_horizon",
    "run_online",
    "COMPLETE",
    "NEGLIGIBLE",
    "config_summary",
    "model_job",
    "StopModeller",
    "EpochStore",
    "log_event",
    "StopVerdict",
    "stop_verdict",
    "MotionNoiseConfig",
    "MotionNoiseLearner",
    "MotionNoisePrior",
    "add_motion_gm",
    "ned_offset",
    "horizontal_distance",
]
