"""Simulator (SPEC §10): urban drives with known truth and long static recordings.

``simulate_drive(DriveConfig(...), imu_models, seed)`` returns a :class:`SimulatedDrive` (IMU with and
without errors, GNSS, reference, truth, static mask) whose ``write(dir)`` produces the KF-GINS files and
a ``dataset.json`` manifest; ``simulate_static(models, duration_s, rate_hz, seed)`` a static recording.

It makes input for every stage of the data path (IMU → detection → modelling → filter) with the truth
to check them; it imports the model algebra, :mod:`imunoise.nav` (Earth model, attitude) and
:mod:`imunoise.io` (data classes, writers), and only :mod:`imunoise.experiments` and the CLI import it.
"""

from imunoise.sim.drive import DriveConfig, SimulatedDrive, plan_drive, simulate_drive
from imunoise.sim.imu_errors import AXES, PRESETS, paper_models, preset_model, resolve_imu_models
from imunoise.sim.static import StaticRecording, simulate_static

__all__ = [
    "AXES",
    "PRESETS",
    "DriveConfig",
    "SimulatedDrive",
    "StaticRecording",
    "plan_drive",
    "paper_models",
    "preset_model",
    "resolve_imu_models",
    "simulate_drive",
    "simulate_static",
]
