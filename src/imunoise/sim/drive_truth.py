"""The truth record of a simulated drive (``truth.json``, docs/guide/theory.rst, 'Simulator'): the injected errors,
stops, turns, outages and the initial state."""

from __future__ import annotations

import math
from dataclasses import asdict
from typing import Any

import numpy as np

from imunoise.imu import AXES
from imunoise.noise.model import Model
from imunoise.sim.drive_config import DriveConfig
from imunoise.sim.imu_errors import models_to_json
from imunoise.sim.trajectory import DrivePlan, Kinematics

__all__ = ["truth_record"]


def _intervals(mask: np.ndarray, t: np.ndarray) -> list[list[float]]:
    """[t_first, t_last] of each run of True in ``mask``."""
    m = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(m)
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1
    return [[float(t[a]), float(t[b])] for a, b in zip(starts, ends, strict=True)]


def truth_record(
    cfg: DriveConfig,
    seed: int,
    plan: DrivePlan,
    kin: Kinematics,
    at: np.ndarray,
    models: dict[str, Model],
    bias: np.ndarray,
    scale: np.ndarray,
    outlier_t: np.ndarray,
    static_mask: np.ndarray,
    t: np.ndarray,
) -> dict[str, Any]:
    """The ``truth.json`` content of a drive: everything injected, in GPS seconds of week
    (docs/guide/theory.rst, 'Simulator')."""
    s0 = cfg.start_sow
    step = max(1, int(round(cfg.imu_rate_hz)))
    wz = np.degrees(kin.omega_ib_b[at, 2])
    return {
        "seed": seed,
        "units": {
            "time": "GPS seconds of week",
            "gyro": "rad/s (model parameters per sample at imu_rate_hz)",
            "accel": "m/s² (model parameters per sample at imu_rate_hz)",
            "angles": "degrees unless the key says rad",
        },
        "imu_rate_hz": cfg.imu_rate_hz,
        "error_equation": "rate_meas = (1 + scale) * rate_true + turn_on_bias + model_error + vibration; "
        "increment = rate_meas * dt",
        "models": models_to_json(models, cfg.imu_rate_hz),
        "turn_on_bias": {"gyro_rad_s": bias[:3], "accel_m_s2": bias[3:], "axes": list(AXES)},
        "scale_factor": {"gyro": scale[:3], "accel": scale[3:]},
        "vibration_std_at_speed": {
            "gyro_rad_s": cfg.gyro_vibration,
            "accel_m_s2": cfg.accel_vibration,
            "full_at_mps": 3.0,
        },
        "stops": [[s0 + a, s0 + b] for a, b in plan.stops],
        "static_intervals": [[s0 + a, s0 + b] for a, b in plan.static_intervals],
        "static_mask_intervals": _intervals(static_mask, t),
        "turns": [{**tr, "t0": s0 + tr["t0"]} for tr in plan.turns],
        "max_turn_rate_deg_s": float(np.abs(wz).max()),
        "max_speed_mps": float(kin.speed.max()),
        "distance_m": float(np.sum(kin.speed[at]) / cfg.imu_rate_hz),
        "speed_profile": {"t": t[::step], "speed_mps": kin.speed[at][::step]},
        "gnss_outliers_t": outlier_t,
        "outages": [[s0 + s, d] for s, d in cfg.outages],
        "initial_state": {
            "t": float(t[0]),
            "llh_deg_m": [
                math.degrees(kin.llh[at[0], 0]),
                math.degrees(kin.llh[at[0], 1]),
                kin.llh[at[0], 2],
            ],
            "vel_ned_mps": kin.vel[at[0]],
            "euler_deg": np.degrees(kin.euler[at[0]]),
        },
        "config": asdict(cfg),
    }
