"""Motion-dependent IMU errors: larger white noise and faster bias wander while the car moves.

A stop shows the IMU's static errors; a moving car adds vibration and makes the biases wander faster
(temperature, g-sensitivity, mounting). On the shared real drive (``data/drive_0708``) the gyro errors the
GNSS-aided filter estimates while driving wander far more than the stops predict: the std of their 10 s
means is 58 / 144 / 123 °/h (x/y/z) against a static ADEV at 10 s of 64 / 37 / 6 °/h (:data:`REAL_DRIVE_GYRO`;
an upper bound, the estimates include estimation noise). The simulator reproduces this with a per-axis
multiplier law.

Law. For sensor axis j (:data:`imunoise.imu.AXES`) and IMU sample k with speed v_k and body turn rate
ω_k = ‖(φ̇, θ̇, ψ̇)‖ (Euler-angle rates of the vehicle, zero at rest):

    g_k = min(v_k / v_ref, 1),   h_k = min(ω_k / ω_ref, 1),
    m^w_{j,k} = 1 + a^w_j g_k + b^w_j h_k,       m^b_{j,k} = 1 + a^b_j g_k + b^b_j h_k,

and m = 1 exactly on the static epochs (the static mask), so a stop is the static model. The axis' model
components are driven with time-varying noise:

    WN:   w_k = m^w_k σ ε_k,
    RW:   x_k = x_{k−1} + m^b_k γ ε_k,
    AR1:  x_k = φ x_{k−1} + m^b_k σ ε_k          (T_c unchanged; stationary σ_GM scales with m^b),
    QN, DR: unchanged,

with the same standard normals ε_k as the static simulation (a time-varying σ on a white sequence is exactly
a per-sample scaling of its innovations), so the all-ones law reproduces the static path bit for bit.
Speed and turn rate are smooth (quintic ramps), so the multipliers need no further smoothing.

Moving regime (the oracle). The filter of the ``oracle`` method gets, per axis, the static model with
σ²_WN·M_w², γ²_RW·M_b², σ²_AR1·M_b², where M² = mean of m² over the moving samples (the variance the law
injects while moving); QN and DR stay. :func:`oracle_models`.

Presets (:data:`MOTION_PRESETS`): ``"none"`` — every multiplier 1 (static = moving, the paper's premise:
nothing extra to learn in motion); ``"drive0708"`` (:data:`DEFAULT_MOTION`) — calibrated on the real drive
(``scripts/calibrate_motion_noise.py``): see :data:`DRIVE0708`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.imu import AXES
from imunoise.model import Model
from imunoise.processes import AR1, RW, WN

__all__ = [
    "MotionNoise",
    "MOTION_PRESETS",
    "DEFAULT_MOTION",
    "DRIVE0708",
    "REAL_DRIVE_GYRO",
    "resolve_motion",
    "modulated_errors",
    "scaled_models",
    "oracle_models",
]

_N = len(AXES)
_ZERO = (0.0,) * _N

# The real drive (data/drive_0708, notes "What no stop shows"): std of 10 s means of the gyro errors the
# GNSS-aided filter estimates while driving, and the static ADEV at 10 s, °/h, axes x/y/z.
REAL_DRIVE_GYRO = {"moving_std_10s_dph": (58.0, 144.0, 123.0), "static_adev_10s_dph": (64.0, 37.0, 6.0)}


@dataclass(frozen=True)
class MotionNoise:
    """Per-axis motion law (module docstring): multipliers of the white-noise σ (``white_*``) and of the
    bias-process driving noise σ (``bias_*``) per unit of speed activity (``*_speed``, g = min(v/v_ref, 1))
    and of turn activity (``*_turn``, h = min(ω/ω_ref, 1), ω the turn rate). Tuples have one entry per axis of
    :data:`imunoise.imu.AXES` (gyro x, y, z, accel x, y, z); all ≥ 0.

    Raises
    ------
    ModelError
        For a tuple of the wrong length, a negative or non-finite coefficient, or a reference ≤ 0.
    """

    name: str = "custom"
    white_speed: tuple[float, ...] = _ZERO
    white_turn: tuple[float, ...] = _ZERO
    bias_speed: tuple[float, ...] = _ZERO
    bias_turn: tuple[float, ...] = _ZERO
    speed_ref_mps: float = 3.0
    turn_ref_deg_s: float = 30.0

    def __post_init__(self) -> None:
        for key in ("white_speed", "white_turn", "bias_speed", "bias_turn"):
            val = tuple(float(x) for x in getattr(self, key))
            if len(val) != _N or not all(math.isfinite(x) and x >= 0 for x in val):
                raise ModelError(f"MotionNoise.{key} needs {_N} finite values ≥ 0 (axes {', '.join(AXES)}), "
                                 f"got {getattr(self, key)!r}")
            object.__setattr__(self, key, val)
        if not (self.speed_ref_mps > 0 and self.turn_ref_deg_s > 0):
            raise ModelError(f"MotionNoise references must be > 0, got speed_ref_mps={self.speed_ref_mps}, "
                             f"turn_ref_deg_s={self.turn_ref_deg_s}")

    @property
    def is_static(self) -> bool:
        """True when every multiplier is 1 (moving = static)."""
        return not any(any(getattr(self, k)) for k in ("white_speed", "white_turn", "bias_speed", "bias_turn"))

    def multipliers(self, speed: np.ndarray, turn_rate: np.ndarray,
                    static_mask: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(m^w, m^b), each (n, 6): the module docstring's law at speeds [m/s] and turn rates [rad/s];
        exactly 1 where ``static_mask`` is True."""
        g = np.minimum(np.abs(np.asarray(speed, dtype=float)) / self.speed_ref_mps, 1.0)[:, None]
        h = np.minimum(np.abs(np.asarray(turn_rate, dtype=float)) / math.radians(self.turn_ref_deg_s), 1.0)[:, None]
        mw = 1.0 + np.asarray(self.white_speed) * g + np.asarray(self.white_turn) * h
        mb = 1.0 + np.asarray(self.bias_speed) * g + np.asarray(self.bias_turn) * h
        if static_mask is not None:
            mw[static_mask] = 1.0
            mb[static_mask] = 1.0
        return mw, mb

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "axes": list(AXES)}


NONE = MotionNoise(name="none")

# Calibrated on the experiments' default scenario (paper IMU preset, 600 s drives with 4 stops) by
# scripts/calibrate_motion_noise.py against the real drive's ratio (std of 10 s means while moving) / (static
# ADEV at 10 s) per gyro axis: 0.91 / 3.9 / 20.5. Gyro x gets no bias amplification: the static model alone
# already gives a larger ratio there (its rate random walk accumulates over a drive). White noise: ×3 on the
# gyros and ×7 on the accelerometers at speed, the earlier simulator's vibration (0.1 °/s and 0.05 m/s² per
# sample at ≥ 3 m/s) against the white σ of the paper/mems presets. The real drive's regressions of the
# errors on speed and |ω_z| explain little (R² 0.08–0.30), so the preset is a moving/at-rest switch ramped
# by speed; the turn terms are 0.
DRIVE0708 = MotionNoise(
    name="drive0708",
    white_speed=(2.0, 2.0, 2.0, 6.0, 6.0, 6.0),
    bias_speed=(0.0, 2.75, 4.8, 0.0, 0.0, 0.0),
)

MOTION_PRESETS: dict[str, MotionNoise] = {"none": NONE, "drive0708": DRIVE0708}
DEFAULT_MOTION = "drive0708"


def resolve_motion(spec: str | MotionNoise) -> MotionNoise:
    """A :class:`MotionNoise` from a preset name (:data:`MOTION_PRESETS`) or a MotionNoise (returned as is).

    Raises
    ------
    ModelError
        For an unknown name or another type, listing the presets.
    """
    if isinstance(spec, MotionNoise):
        return spec
    if isinstance(spec, str) and spec.lower() in MOTION_PRESETS:
        return MOTION_PRESETS[spec.lower()]
    raise ModelError(f"unknown motion-noise preset {spec!r}; choose one of {', '.join(MOTION_PRESETS)} "
                     "(or pass a MotionNoise)")


def _axis_path(model: Model, n: int, rng: np.random.Generator, mw: np.ndarray, mb: np.ndarray) -> np.ndarray:
    """One axis' path with modulated innovations; the same draws, in the same order, as
    :meth:`Model.simulate` (which the all-ones law must reproduce exactly)."""
    from scipy.signal import lfilter

    parts = []
    for c in model.components:
        if isinstance(c, WN):
            parts.append(rng.normal(0.0, math.sqrt(c.values[0]), n) * mw)
        elif isinstance(c, RW):
            parts.append(np.cumsum(rng.normal(0.0, math.sqrt(c.values[0]), n) * mb))
        elif isinstance(c, AR1):
            phi, s2 = c.values
            e = rng.normal(0.0, math.sqrt(s2), n) * mb
            x0 = rng.normal(0.0, math.sqrt(s2 / (1.0 - phi * phi))) * mb[0]  # stationary in the first regime
            parts.append(lfilter([1.0], [1.0, -phi], e, zi=[phi * x0])[0])
        else:  # QN, DR: quantisation and a deterministic ramp do not depend on motion
            parts.append(c.simulate(n, rng))
    return np.sum(parts, axis=0)


def modulated_errors(models: Mapping[str, Model], n: int, seed: int | np.random.SeedSequence,
                     m_white: np.ndarray, m_bias: np.ndarray) -> np.ndarray:
    """Per-sample errors (n, 6), axes :data:`imunoise.imu.AXES`, with per-sample multipliers ``m_white``
    and ``m_bias`` (n, 6) on the white and bias-process noise (module docstring). Streams per axis as
    :func:`imunoise.sim.imu_errors.simulate_model_errors`: with all-ones multipliers the output is identical."""
    m_white = np.asarray(m_white, dtype=float)
    m_bias = np.asarray(m_bias, dtype=float)
    if m_white.shape != (n, _N) or m_bias.shape != (n, _N):
        raise ModelError(f"multipliers must have shape ({n}, {_N}), got {m_white.shape} and {m_bias.shape}")
    ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    streams = ss.spawn(_N)
    out = np.zeros((n, _N))
    for j, ax in enumerate(AXES):
        if ax in models:
            out[:, j] = _axis_path(models[ax], n, np.random.default_rng(streams[j]), m_white[:, j], m_bias[:, j])
    return out


def scaled_models(models: Mapping[str, Model], m_white: np.ndarray, m_bias: np.ndarray) -> dict[str, Model]:
    """Each axis' model with WN σ² × M_w², RW γ² × M_b², AR1 σ² × M_b² (T_c kept); QN, DR unchanged.
    ``m_white``/``m_bias``: one multiplier per axis of :data:`imunoise.imu.AXES`."""
    return {ax: models[ax].scaled(white=float(m_white[j]) ** 2, bias=float(m_bias[j]) ** 2)
            for j, ax in enumerate(AXES) if ax in models}


def oracle_models(models: Mapping[str, Model], motion: str | MotionNoise, speed: np.ndarray | None = None,
                  turn_rate: np.ndarray | None = None) -> dict[str, Model]:
    """The moving-regime per-axis models (module docstring): ``models`` scaled by M = √mean(m²) over the
    given moving samples (``speed`` [m/s], ``turn_rate`` [rad/s]); without samples, at cruise (g = 1, h = 0).

    Parameters
    ----------
    models : mapping
        Static per-axis models (keys of :data:`imunoise.imu.AXES`), known parameters.
    motion : str or MotionNoise
        The law (a preset name or a :class:`MotionNoise`).
    speed, turn_rate : numpy.ndarray, optional
        Speed and turn rate at the moving samples, both or neither.

    Returns
    -------
    dict
        ``{axis: Model}``, the static models when the law is ``"none"``.
    """
    law = resolve_motion(motion)
    if (speed is None) != (turn_rate is None):
        raise ModelError("oracle_models needs both speed and turn_rate, or neither (cruise regime)")
    if speed is None:
        speed, turn_rate = np.array([law.speed_ref_mps]), np.array([0.0])
    if len(speed) == 0:
        return dict(models)
    mw, mb = law.multipliers(speed, turn_rate)
    return scaled_models(models, np.sqrt(np.mean(mw * mw, axis=0)), np.sqrt(np.mean(mb * mb, axis=0)))
