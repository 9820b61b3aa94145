"""Simulator (docs/guide/theory.rst, 'Simulator'): urban drives with known truth and long static recordings.

``simulate_drive(DriveConfig(...), imu_models, seed)`` returns a :class:`SimulatedDrive` (IMU with and
without errors, GNSS, reference, truth, static mask) whose ``write(dir)`` produces the KF-GINS files and
a ``dataset.json`` manifest; ``simulate_static(models, duration_s, rate_hz, seed)`` a static recording.
``DriveConfig(motion_noise=...)`` makes the errors grow while moving (:mod:`imunoise.sim.motion`; a shipped law's
name or a law file, ``load_law(path)``).

It makes input for every stage of the data path (IMU → detection → modelling → filter) with the truth
to check them; it imports the model algebra, :mod:`imunoise.nav` (Earth model, attitude) and
:mod:`imunoise.io` (data classes, writers), and only :mod:`imunoise.experiments` and the CLI import it.
"""

from imunoise.sim.drive import DriveConfig, SimulatedDrive, plan_drive, simulate_drive
from imunoise.sim.imu_errors import AXES, PRESETS, paper_models, preset_model, resolve_imu_models
from imunoise.sim.motion import (
    DEFAULT_MOTION,
    LAWS,
    MOTION_PRESETS,
    MotionNoise,
    load_law,
    oracle_models,
    resolve_motion,
)
from imunoise.sim.static import StaticRecording, simulate_static

__all__ = [
    "AXES",
    "DEFAULT_MOTION",
    "LAWS",
    "MOTION_PRESETS",
    "MotionNoise",
    "PRESETS",
    "DriveConfig",
    "SimulatedDrive",
    "StaticRecording",
    "load_law",
    "oracle_models",
    "plan_drive",
    "paper_models",
    "preset_model",
    "resolve_imu_models",
    "resolve_motion",
    "simulate_drive",
    "simulate_static",
]
