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

and m = 1 exactly on the static epochs (the static mask), so a stop is the static model.
How the multipliers drive the model's components, and the moving-regime models of the oracle: below.

A third activity, acceleration: c_k = min(‖a_k‖ / a_ref, 1) with a_k = f_k − g_k the specific force with
gravity removed (the vehicle's acceleration, computed from the trajectory as dv_n/dt), enters both
multipliers as ``+ c^w_j c_k`` and ``+ c^b_j c_k``.

Additive terms (:mod:`imunoise.sim.law_terms`, drawn from their own random stream, so a law without them
draws exactly what it drew before they existed):

    moving Gauss–Markov   x_k = φ x_{k−1} + σ√(1 − φ²) ε_k while moving, x_k = x_{k−1} at stops, φ = e^{−Δt/τ},
    departure step        b_k = Σ_{departures ≤ k} s_i,  s_i ~ N(0, σ²) at each start from a stop,
    warm-up               b(t) = A (1 − exp(−(t − t_0)/τ)) from power-on t_0.

Law files (:func:`load_law`, ``--motion-noise FILE.json``): every key optional (absent = no effect), per-axis
lists of 6 in the order gyro x, y, z, accel x, y, z, SI units (rad/s, m/s², s)::

    {"name": "example", "doc": "what it models and why these numbers",
     "speed_ref_mps": 3.0, "turn_ref_deg_s": 30.0, "accel_ref_mps2": 2.0,
     "white": {"speed": [6], "turn": [6], "accel": [6]},
     "bias":  {"speed": [6], "turn": [6], "accel": [6]},
     "moving_gm": {"sigma": [6], "tau_s": [6]},
     "departure_step": [6],
     "warmup": {"amplitude": [6], "tau_s": 600.0}}

Shipped laws (``src/imunoise/sim/laws/*.json``, by name: :data:`LAWS`): the presets ``"none"`` — every
multiplier 1 (static = moving, the paper's premise: nothing extra to learn in motion) and ``"drive0708"``
(:data:`DEFAULT_MOTION`) — calibrated on the real drive (``scripts/calibrate_motion_noise.py``, see
:data:`DRIVE0708`); and one law per additive term, each with its numbers and reasons in its ``doc``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from imunoise.errors import ModelError
from imunoise.imu import AXES
from imunoise.noise.model import Model
from imunoise.noise.processes import AR1, RW, WN
from imunoise.sim.law_files import (
    DEFAULT_MOTION,
    DRIVE0708,
    LAW_DIR,
    LAWS,
    MOTION_PRESETS,
    NONE,
    law_from_dict,
    load_law,
    motion_arg,
    resolve_motion,
)
from imunoise.sim.motion_law import MotionNoise

__all__ = [
    "MotionNoise",
    "MOTION_PRESETS",
    "DEFAULT_MOTION",
    "DRIVE0708",
    "REAL_DRIVE_GYRO",
    "LAWS",
    "load_law",
    "law_from_dict",
    "resolve_motion",
    "motion_arg",
    "modulated_errors",
    "scaled_models",
    "oracle_models",
    # the law's coefficients live in motion_law, its files and the shipped laws in law_files; importable from here
    "LAW_DIR",
    "NONE",
]

_N = len(AXES)

# The real drive (data/drive_0708, notes "What no stop shows"): std of 10 s means of the gyro errors the
# GNSS-aided filter estimates while driving, and the static ADEV at 10 s, °/h, axes x/y/z.
REAL_DRIVE_GYRO = {"moving_std_10s_dph": (58.0, 144.0, 123.0), "static_adev_10s_dph": (64.0, 37.0, 6.0)}

# ----------------------------------------------------------------------------------------------
# Motion-modulated error paths and the oracle's moving-regime models
#
# Motion-modulated IMU error paths and the oracle's moving-regime models (the multiplier law of
# :mod:`imunoise.sim.motion`).
#
# With the law's multipliers m^w_{j,k}, m^b_{j,k} (1 exactly on the static epochs), the axis' model components are
# driven with time-varying noise:
#
#     WN:   w_k = m^w_k σ ε_k,
#     RW:   x_k = x_{k−1} + m^b_k γ ε_k,
#     AR1:  x_k = φ x_{k−1} + m^b_k σ ε_k          (T_c unchanged; stationary σ_GM scales with m^b),
#     QN, DR: unchanged,
#
# with the same standard normals ε_k as the static simulation (a time-varying σ on a white sequence is exactly
# a per-sample scaling of its innovations), so the all-ones law reproduces the static path bit for bit.
# Speed and turn rate are smooth (quintic ramps), so the multipliers need no further smoothing.
#
# Moving regime (the oracle). The filter of the ``oracle`` method gets, per axis, the static model with
# σ²_WN·M_w², γ²_RW·M_b², σ²_AR1·M_b², where M² = mean of m² over the moving samples (the variance the law
# injects while moving); QN and DR stay. :func:`oracle_models`.
# ----------------------------------------------------------------------------------------------



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
                  turn_rate: np.ndarray | None = None, accel: np.ndarray | None = None,
                  rate_hz: float | None = None) -> dict[str, Model]:
    """The moving-regime per-axis models (module docstring): ``models`` scaled by M = √mean(m²) over the
    given moving samples (``speed`` [m/s], ``turn_rate`` [rad/s], ``accel`` ‖f − g‖ [m/s²]); without samples,
    at cruise (g = 1, h = 0, c = 0). A moving Gauss–Markov of the law is added as one more AR1 (its σ and τ at
    ``rate_hz``) on the axes that carry it; departure steps and the warm-up have no constant-model form and
    are left out (the law-aware oracle of issue 21 §2 takes them per sample).

    Parameters
    ----------
    models : mapping
        Static per-axis models (keys of :data:`imunoise.imu.AXES`), known parameters.
    motion : str or MotionNoise
        The law (a shipped law's name, a law file or a :class:`MotionNoise`).
    speed, turn_rate : numpy.ndarray, optional
        Speed and turn rate at the moving samples, both or neither.
    accel : numpy.ndarray, optional
        Acceleration magnitude at the same samples (the law's acceleration activity; None: 0).
    rate_hz : float, optional
        IMU rate, needed when the law has a moving Gauss–Markov.

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
    mw, mb = law.multipliers(speed, turn_rate, accel=accel)
    out = scaled_models(models, np.sqrt(np.mean(mw * mw, axis=0)), np.sqrt(np.mean(mb * mb, axis=0)))
    if any(law.moving_gm_sigma):
        if rate_hz is None:
            raise ModelError("oracle_models needs rate_hz for a law with a moving Gauss-Markov")
        for j, ax in enumerate(AXES):
            sg, tau = law.moving_gm_sigma[j], law.moving_gm_tau_s[j]
            if sg > 0 and ax in out:
                phi = math.exp(-1.0 / (tau * rate_hz))
                out[ax] = Model([*out[ax].components, AR1(phi=phi, sigma2=sg * sg * (1.0 - phi * phi))])
    return out
