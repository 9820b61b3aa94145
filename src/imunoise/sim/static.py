"""Long static recording for a given IMU error model (the paper's 2 h static test, docs/guide/theory.rst, 'Simulator').

A motionless IMU at ``llh`` with attitude ``euler`` senses the Earth rate and gravity only:
ω_ib^b = C_n^b ω_ie^n and f^b = −C_n^b g^n with g^n = [0, 0, g(lat, h)] (normal gravity), constant in
time, so the increments are exactly rate·Δt. Errors per axis enter the rates as in a drive (see
:mod:`imunoise.sim.drive`): r̃_k = r + b + e_k.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.imu import AXES, ImuData
from imunoise.nav.earth import OMEGA_E, euler_to_dcm, gravity
from imunoise.noise.model import Model
from imunoise.sim.imu_errors import models_to_json, resolve_imu_models, simulate_model_errors

__all__ = ["StaticRecording", "simulate_static"]


@dataclass(eq=False)
class StaticRecording:
    """``rates`` (n, 6) = [gyro_x, gyro_y, gyro_z (rad/s), accel_x, accel_y, accel_z (m/s²)] with errors;
    ``rates_true`` the constant Earth-rate/gravity signal; ``errors`` = rates − rates_true (bias + model path);
    ``imu`` the same as increments."""

    t: np.ndarray
    rates: np.ndarray
    rates_true: np.ndarray
    errors: np.ndarray
    imu: ImuData
    models: dict[str, Model]
    truth: dict[str, Any]

    @property
    def increments(self) -> np.ndarray:
        """(n, 6) increments [Δθ (rad), Δv (m/s)] = rates·Δt."""
        return np.column_stack([self.imu.dtheta, self.imu.dv])


def simulate_static(
    model_per_axis: Any,
    duration_s: float = 7200.0,
    rate_hz: float = 100.0,
    seed: int = 0,
    *,
    llh_deg: tuple[float, float, float] = (40.0966, -105.147, 1601.0),
    euler_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
    gyro_bias_sigma: float = 0.0,
    accel_bias_sigma: float = 0.0,
    start_sow: float = 0.0,
) -> StaticRecording:
    """Static recording of ``duration_s`` at ``rate_hz`` with per-axis errors from ``model_per_axis``
    (anything :func:`~imunoise.sim.imu_errors.resolve_imu_models` accepts) plus optional turn-on biases
    drawn with the given σ (rad/s, m/s²)."""
    if not duration_s > 0 or not rate_hz > 0:
        raise ModelError(f"need duration_s > 0 and rate_hz > 0, got {duration_s}, {rate_hz}")
    n = int(round(duration_s * rate_hz))
    if n < 2:
        raise ModelError(
            f"a static recording needs at least 2 samples, got {n} from {duration_s:g} s at {rate_hz:g} Hz; "
            "give a longer duration or higher rate"
        )
    dt = 1.0 / rate_hz
    t = start_sow + dt * np.arange(1, n + 1)
    lat, h = math.radians(llh_deg[0]), float(llh_deg[2])
    C_nb = euler_to_dcm(*np.radians(euler_deg)).T
    w = C_nb @ np.array([OMEGA_E * math.cos(lat), 0.0, -OMEGA_E * math.sin(lat)])
    f = C_nb @ np.array([0.0, 0.0, -gravity(lat, h)])
    true = np.concatenate([w, f])
    models = resolve_imu_models(model_per_axis, rate_hz)
    ss_err, ss_bias = np.random.SeedSequence(seed).spawn(2)
    rb = np.random.default_rng(ss_bias)
    bias = np.concatenate([rb.normal(0.0, gyro_bias_sigma, 3), rb.normal(0.0, accel_bias_sigma, 3)])
    errors = simulate_model_errors(models, n, ss_err) + bias
    rates = true + errors
    imu = ImuData(t=t, dtheta=rates[:, :3] * dt, dv=rates[:, 3:] * dt)
    truth = {
        "seed": seed,
        "rate_hz": rate_hz,
        "duration_s": duration_s,
        "models": models_to_json(models, rate_hz),
        "turn_on_bias": {
            "gyro_rad_s": bias[:3].tolist(),
            "accel_m_s2": bias[3:].tolist(),
            "axes": list(AXES),
        },
        "rates_true": true.tolist(),
        "llh_deg_m": list(llh_deg),
        "euler_deg": list(euler_deg),
    }
    return StaticRecording(
        t=t, rates=rates, rates_true=np.tile(true, (n, 1)), errors=errors, imu=imu, models=models, truth=truth
    )
