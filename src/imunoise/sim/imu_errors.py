"""IMU error models for the simulator: presets, per-axis model resolution, error injection
(docs/guide/theory.rst, 'Latent processes' and 'Simulator').

Sensor axes are :data:`imunoise.imu.AXES`: ``gyro_x, gyro_y, gyro_z`` (rad/s) and ``accel_x, accel_y,
accel_z`` (m/s²); inputs may still use the short names ``gx`` … ``az`` of older truth files. A model's
parameters are per sample at the IMU rate (docs/guide/theory.rst, 'Conventions'). Presets are stored as continuous-time
values (noise density, random-walk K, Gauss–Markov T_c and σ, rate ramp) and converted at the requested rate:

    WN σ² = N²·f,  RW γ² = K²/f,  AR1 φ = exp(−1/(T_c f)), σ² = σ²_GM (1 − φ²),
    DR ω = R/f,  QN Q² = (Q_IEEE f)²

(inverse of the docs/guide/theory.rst, 'Latent processes' "continuous-time equivalent" column).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.imu import ACCEL_AXES, AXES, GYRO_AXES, canonical_axis
from imunoise.noise.model import Model
from imunoise.noise.processes import AR1, DR, QN, RW, WN

__all__ = [
    "AXES",
    "GYRO_AXES",
    "ACCEL_AXES",
    "PRESETS",
    "preset_model",
    "paper_models",
    "PAPER_TABLE4_GYRO",
    "resolve_imu_models",
    "models_to_json",
]

_DEG = math.pi / 180.0
_DPH = _DEG / 3600.0  # °/h in rad/s

# Consumer-grade MEMS, in the spirit of paper Table 4 and of the shared drive's datasheet numbers
# (gyro 0.0038 °/s/√Hz, accel 70 µg/√Hz). AR1 entries: (T_c [s], σ_GM [unit]); the first k are used
# when a structure asks for k × AR1 (slowest first, as the canonical order).
PRESETS: dict[str, dict[str, dict[str, Any]]] = {
    "mems": {
        "gyro": {
            "WN": 0.0038 * _DEG,  # noise density, rad/s/√Hz  (ARW 0.23 °/√h)
            "RW": 0.5 * _DPH,  # rate random walk K, rad/s/√s (0.5 °/h/√s)
            "AR1": [(200.0, 10.0 * _DPH), (20.0, 20.0 * _DPH), (2.0, 10.0 * _DPH), (0.1, 0.01 * _DEG)],
            "QN": 1e-7,  # Q_IEEE, rad
            "DR": 0.01 * _DPH,  # rate ramp, rad/s²  (0.01 °/h/s)
        },
        "accel": {
            "WN": 70e-6 * 9.80665,  # m/s²/√Hz (VRW 0.041 m/s/√h)
            "RW": 1e-4,  # m/s²/√s
            "AR1": [(200.0, 3e-3), (20.0, 5e-3), (2.0, 2e-3), (0.1, 5e-3)],
            "QN": 1e-5,  # Q_IEEE, m/s
            "DR": 1e-6,  # m/s³
        },
    },
    "tactical": {
        "gyro": {
            "WN": 0.15 * _DEG / 60.0,  # 0.15 °/√h
            "RW": 0.02 * _DPH,
            "AR1": [(300.0, 1.0 * _DPH), (30.0, 0.5 * _DPH), (3.0, 0.5 * _DPH), (0.1, 2.0 * _DPH)],
            "QN": 1e-8,
            "DR": 0.0005 * _DPH,
        },
        "accel": {
            "WN": 30e-6 * 9.80665,
            "RW": 1e-5,
            "AR1": [(300.0, 3e-4), (30.0, 2e-4), (3.0, 2e-4), (0.1, 5e-4)],
            "QN": 1e-6,
            "DR": 1e-7,
        },
    },
    # A cheap MEMS noisier than "mems" (accel 500 µg/√Hz: 0.049 m/s² per sample at 100 Hz, about the simulated
    # cruising vibration of 0.05 m/s²). A λ_0 learned at its first stop (≈ 2σ) lets smooth cruising pass the
    # IMU-only static test (measured: epoch precision 0.5–0.6 on 600 s simulated drives, 1.0 with "mems"): the
    # stress case for the online engine's stop guard (OnlineConfig.stop_guard).
    "noisy": {
        "gyro": {
            "WN": 0.015 * _DEG,  # rad/s/√Hz (ARW 0.9 °/√h)
            "RW": 2.0 * _DPH,
            "AR1": [(200.0, 30.0 * _DPH), (20.0, 60.0 * _DPH), (2.0, 30.0 * _DPH), (0.1, 0.03 * _DEG)],
            "QN": 3e-7,
            "DR": 0.03 * _DPH,
        },
        "accel": {
            "WN": 500e-6 * 9.80665,  # m/s²/√Hz (VRW 0.29 m/s/√h)
            "RW": 3e-4,
            "AR1": [(200.0, 1e-2), (20.0, 1.5e-2), (2.0, 6e-3), (0.1, 1.5e-2)],
            "QN": 3e-5,
            "DR": 3e-6,
        },
    },
}
PRESETS["default"] = PRESETS["mems"]

# Paper Table 4: the online GMWM estimates (3×AR1 + WN + RW, per sample at 125 Hz) of the three gyros of
# the §3.2 car drive; per axis ([(σ², φ) × 3], σ²_WN, γ²_RW), in rad²/s² per sample. Table 4 prints the AR1
# innovation variances σ_i² and φ_i = β_i as simts reports them. The paper gives no accelerometer model; the
# "paper" preset pairs these gyros with the accelerometers of the "mems" preset.
PAPER_TABLE4_RATE_HZ = 125.0
PAPER_TABLE4_GYRO: dict[str, tuple[list[tuple[float, float]], float, float]] = {
    "gyro_x": ([(3.009e-9, 0.8574), (1.723e-9, 0.8852), (3.064e-7, 0.7512)], 4.551e-7, 1.276e-11),
    "gyro_y": ([(7.156e-11, 0.9979), (4.498e-11, 0.9978), (6.96e-8, 0.7611)], 6.264e-7, 4.171e-15),
    "gyro_z": ([(4.461e-10, 0.9298), (1.871e-10, 0.9961), (2.340e-7, 0.3866)], 1.878e-6, 2.506e-11),
}


def paper_models(rate_hz: float) -> dict[str, Model]:
    """The "paper" preset at ``rate_hz``: gyros from paper Table 4 (exact at 125 Hz; at other rates through the
    continuous equivalents: T_c and σ_GM of each AR1, noise density, rate random walk), accelerometers from
    the "mems" preset. Per-axis 3×AR1 + WN + RW."""
    if not rate_hz > 0:
        raise ModelError(f"IMU rate must be > 0 Hz, got {rate_hz}")
    f0, f = PAPER_TABLE4_RATE_HZ, float(rate_hz)
    out: dict[str, Model] = {}
    for ax, (ars, wn, rw) in PAPER_TABLE4_GYRO.items():
        comps: list = []
        for s2, phi0 in ars:
            var = s2 / (1.0 - phi0 * phi0)  # stationary variance, rate-independent
            phi = phi0 ** (f0 / f)  # same T_c
            comps.append(AR1(phi=phi, sigma2=var * (1.0 - phi * phi)))
        comps.append(WN(sigma2=wn * f / f0))  # same noise density
        comps.append(RW(gamma2=rw * f0 / f))  # same K
        out[ax] = Model(comps)
    acc = preset_model("mems", "accel", DEFAULT_STRUCTURE, f)
    out.update({ax: acc for ax in ACCEL_AXES})
    return out

DEFAULT_STRUCTURE = "3*AR1 + WN + RW"


def preset_model(preset: str, sensor: str, structure: str | Model, rate_hz: float) -> Model:
    """A model with known per-sample parameters at ``rate_hz`` from a preset's continuous values.

    ``sensor`` is "gyro" or "accel"; ``structure`` e.g. ``"3*AR1+WN+RW"`` (up to 4 AR1).
    """
    if preset not in PRESETS:
        raise ModelError(f"unknown IMU preset {preset!r}; choose one of {sorted(PRESETS)}")
    if not rate_hz > 0:
        raise ModelError(f"IMU rate must be > 0 Hz, got {rate_hz}")
    vals = PRESETS[preset][sensor]
    struct = Model.parse(structure) if isinstance(structure, str) else structure
    counts = struct.counts
    if counts["AR1"] > len(vals["AR1"]):
        raise ModelError(f"preset {preset!r} has {len(vals['AR1'])} AR1 components, {counts['AR1']} requested")
    f = float(rate_hz)
    comps = []
    for tc, sgm in vals["AR1"][: counts["AR1"]]:
        phi = math.exp(-1.0 / (tc * f))
        comps.append(AR1(phi=phi, sigma2=sgm * sgm * (1.0 - phi * phi)))
    if counts["WN"]:
        comps.append(WN(sigma2=vals["WN"] ** 2 * f))
    if counts["QN"]:
        comps.append(QN(q2=(vals["QN"] * f) ** 2))
    if counts["RW"]:
        comps.append(RW(gamma2=vals["RW"] ** 2 / f))
    if counts["DR"]:
        comps.append(DR(omega=vals["DR"] / f))
    return Model(comps)


def _as_model(spec: Any, sensor: str, rate_hz: float, preset: str) -> Model:
    if isinstance(spec, Model):
        model = spec
    elif isinstance(spec, Mapping):
        model = Model.from_dict(dict(spec))
    elif isinstance(spec, str):
        if spec in PRESETS:
            return preset_model(spec, sensor, DEFAULT_STRUCTURE, rate_hz)
        model = Model.parse(spec)
        if not model.known:
            return preset_model(preset, sensor, model, rate_hz)
    else:
        raise ModelError(f"cannot use {spec!r} as an IMU error model (Model, model dict, structure or preset)")
    if not model.known:
        model = preset_model(preset, sensor, model, rate_hz)
    return model


def resolve_imu_models(spec: Any, rate_hz: float, *, preset: str = "mems") -> dict[str, Model]:
    """Per-axis error models ``{"gyro_x": Model, ..., "accel_z": Model}`` (keys of :data:`imunoise.imu.AXES`)
    with known parameters.

    ``spec`` may be: ``None`` (no stochastic errors: empty dict); a preset name (``"mems"``,
    ``"tactical"``: 3×AR1 + WN + RW on every axis; ``"paper"``: :func:`paper_models`); a structure string
    such as ``"2*AR1+WN+RW+QN"``
    (parameters taken from ``preset``); a :class:`Model` (used on all six axes as is, or its structure
    with preset values if it has no parameters); a path to a JSON file; or a mapping whose keys are axes
    (``gyro_x``..``accel_z``, or the short ``gx``..``az`` of older files) or groups (``gyro``, ``accel``) and
    whose values are any of the above or a model
    dict ``{"model": "...", "params": {...}}`` (:meth:`Model.to_dict`). Missing axes get no errors.
    """
    if spec is None:
        return {}
    if isinstance(spec, str) and spec == "paper":
        return paper_models(rate_hz)
    if isinstance(spec, (str, Path)) and str(spec).endswith(".json"):
        path = Path(spec)
        if not path.exists():
            raise ModelError(f"IMU model JSON {path} does not exist")
        spec = json.loads(path.read_text())
        if isinstance(spec, Mapping) and "models" in spec:
            spec = spec["models"]
    if isinstance(spec, (str, Model)) or (isinstance(spec, Mapping) and "model" in spec):
        out = {ax: _as_model(spec, "gyro", rate_hz, preset) for ax in GYRO_AXES}
        out.update({ax: _as_model(spec, "accel", rate_hz, preset) for ax in ACCEL_AXES})
        return out
    if not isinstance(spec, Mapping):
        raise ModelError(f"cannot read IMU models from {type(spec).__name__}")
    out: dict[str, Model] = {}
    for key, val in spec.items():
        key_l = str(key).lower()
        if key_l in ("gyro", "accel"):
            axes = GYRO_AXES if key_l == "gyro" else ACCEL_AXES
            for ax in axes:
                out.setdefault(ax, _as_model(val, key_l, rate_hz, preset))
        elif (axis := canonical_axis(key_l)) is not None:
            out[axis] = _as_model(val, "gyro" if axis in GYRO_AXES else "accel", rate_hz, preset)
        else:
            raise ModelError(f"unknown IMU axis {key!r}; use {', '.join(AXES)} (or gx..az), gyro or accel")
    return out


def models_to_json(models: Mapping[str, Model], rate_hz: float) -> dict[str, Any]:
    """JSON-ready description: per axis the model string, per-sample parameters and continuous values."""
    return {ax: {**m.to_dict(), "continuous": m.continuous(rate_hz), "rate_hz": rate_hz} for ax, m in models.items()}


def simulate_model_errors(models: Mapping[str, Model], n: int, seed: int | np.random.SeedSequence) -> np.ndarray:
    """Per-sample errors (n, 6) in axis order gyro_x..accel_z (zeros where an axis has no model); independent
    random streams per axis derived from ``seed``."""
    ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    streams = ss.spawn(len(AXES))
    out = np.zeros((n, len(AXES)))
    for j, ax in enumerate(AXES):
        if ax in models:
            out[:, j] = models[ax].simulate(n, np.random.default_rng(streams[j]))
    return out
