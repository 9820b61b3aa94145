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

import json
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.imu import AXES
from imunoise.model import Model
from imunoise.processes import AR1, RW, WN
from imunoise.sim.law_terms import departure_steps, moving_gauss_markov, warmup_bias

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
    white_accel: tuple[float, ...] = _ZERO
    bias_accel: tuple[float, ...] = _ZERO
    accel_ref_mps2: float = 2.0
    moving_gm_sigma: tuple[float, ...] = _ZERO
    moving_gm_tau_s: tuple[float, ...] = (1.0,) * _N
    departure_step: tuple[float, ...] = _ZERO
    warmup_amplitude: tuple[float, ...] = _ZERO
    warmup_tau_s: float = 600.0

    def __post_init__(self) -> None:
        for key in _TUPLES:
            val = tuple(float(x) for x in getattr(self, key))
            signed = key == "warmup_amplitude"  # a bias, either sign; the rest are σ or multipliers
            if len(val) != _N or not all(math.isfinite(x) and (signed or x >= 0) for x in val):
                raise ModelError(f"MotionNoise.{key} needs {_N} finite values{'' if signed else ' ≥ 0'} "
                                 f"(axes {', '.join(AXES)}), got {getattr(self, key)!r}")
            object.__setattr__(self, key, val)
        for key in ("speed_ref_mps", "turn_ref_deg_s", "accel_ref_mps2", "warmup_tau_s"):
            if not (math.isfinite(getattr(self, key)) and getattr(self, key) > 0):
                raise ModelError(f"MotionNoise.{key} must be > 0, got {getattr(self, key)!r}")
        if not all(t > 0 for t in self.moving_gm_tau_s):
            raise ModelError(f"MotionNoise.moving_gm_tau_s needs {_N} values > 0 s, got {self.moving_gm_tau_s!r}")

    @property
    def modulates(self) -> bool:
        """True when some white or bias multiplier differs from 1 while moving."""
        return any(any(getattr(self, k)) for k in _MULTIPLIERS)

    @property
    def has_terms(self) -> bool:
        """True when the law adds a moving Gauss–Markov, departure steps or a warm-up."""
        return any(any(getattr(self, k)) for k in ("moving_gm_sigma", "departure_step", "warmup_amplitude"))

    @property
    def is_static(self) -> bool:
        """True when moving = static: every multiplier 1 and no additive term."""
        return not (self.modulates or self.has_terms)

    def multipliers(self, speed: np.ndarray, turn_rate: np.ndarray, static_mask: np.ndarray | None = None,
                    accel: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(m^w, m^b), each (n, 6): the module docstring's law at speeds [m/s], turn rates [rad/s] and
        acceleration magnitudes ‖f − g‖ [m/s²] (``accel``; None: no acceleration activity); exactly 1 where
        ``static_mask`` is True."""
        g = np.minimum(np.abs(np.asarray(speed, dtype=float)) / self.speed_ref_mps, 1.0)[:, None]
        h = np.minimum(np.abs(np.asarray(turn_rate, dtype=float)) / math.radians(self.turn_ref_deg_s), 1.0)[:, None]
        mw = 1.0 + np.asarray(self.white_speed) * g + np.asarray(self.white_turn) * h
        mb = 1.0 + np.asarray(self.bias_speed) * g + np.asarray(self.bias_turn) * h
        if accel is not None and (any(self.white_accel) or any(self.bias_accel)):
            c = np.minimum(np.abs(np.asarray(accel, dtype=float)) / self.accel_ref_mps2, 1.0)[:, None]
            mw = mw + np.asarray(self.white_accel) * c
            mb = mb + np.asarray(self.bias_accel) * c
        if static_mask is not None:
            mw[static_mask] = 1.0
            mb[static_mask] = 1.0
        return mw, mb

    def additive_errors(self, t: np.ndarray, static_mask: np.ndarray, rate_hz: float,
                        seed: int | np.random.SeedSequence) -> np.ndarray:
        """(n, 6) sum of the law's additive terms (:mod:`imunoise.sim.law_terms`) at sample times ``t`` [s];
        draws from ``seed``: the moving Gauss–Markov first, then the departure steps."""
        n = len(t)
        out = np.zeros((n, _N))
        rng = np.random.default_rng(seed)
        if any(self.moving_gm_sigma):
            out += moving_gauss_markov(static_mask, rate_hz, np.array(self.moving_gm_sigma),
                                       np.array(self.moving_gm_tau_s), rng)
        if any(self.departure_step):
            out += departure_steps(static_mask, np.array(self.departure_step), rng)
        if any(self.warmup_amplitude):
            out += warmup_bias(t, np.array(self.warmup_amplitude), self.warmup_tau_s)
        return out

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "axes": list(AXES)}


_MULTIPLIERS = ("white_speed", "white_turn", "white_accel", "bias_speed", "bias_turn", "bias_accel")
_TUPLES = (*_MULTIPLIERS, "moving_gm_sigma", "moving_gm_tau_s", "departure_step", "warmup_amplitude")


LAW_DIR = "laws"  # package folder of the shipped law files (imunoise/sim/laws/*.json)
_ACTIVITIES = ("speed", "turn", "accel")
_KEYS = ("name", "doc", "speed_ref_mps", "turn_ref_deg_s", "accel_ref_mps2", "white", "bias", "moving_gm",
         "departure_step", "warmup")


def _six(where: str, key: str, v: Any, *, positive: bool = False) -> tuple[float, ...]:
    ok = isinstance(v, list) and len(v) == _N and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                        and math.isfinite(x) for x in v)
    if not ok or not all((x > 0) if positive else (x >= 0) for x in v):
        raise ModelError(f"{where}: key '{key}' needs a list of {_N} numbers {'> 0' if positive else '≥ 0'} "
                         f"(gyro x, y, z, accel x, y, z; SI units), got {v!r}")
    return tuple(float(x) for x in v)


def _number(where: str, key: str, v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
        raise ModelError(f"{where}: key '{key}' needs a number > 0, got {v!r}")
    return float(v)


def _table(where: str, key: str, v: Any, allowed: tuple[str, ...]) -> dict:
    if not isinstance(v, dict):
        raise ModelError(f"{where}: key '{key}' needs an object with keys {', '.join(allowed)}, got {v!r}")
    bad = [k for k in v if k not in allowed]
    if bad:
        raise ModelError(f"{where}: unknown key '{key}.{bad[0]}' (allowed: {', '.join(allowed)})")
    return v


def law_from_dict(d: Any, where: str = "motion law") -> MotionNoise:
    """A :class:`MotionNoise` from the law-file schema (module docstring); ``where`` names the source in the
    one-line error.

    Raises
    ------
    ModelError
        Naming the first bad key (unknown key, wrong length or type, negative value, missing τ).
    """
    if not isinstance(d, dict):
        raise ModelError(f"{where}: a law file holds one JSON object, got {type(d).__name__}")
    bad = [k for k in d if k not in _KEYS]
    if bad:
        raise ModelError(f"{where}: unknown key '{bad[0]}' (allowed: {', '.join(_KEYS)})")
    kw: dict[str, Any] = {}
    if "name" in d:
        if not isinstance(d["name"], str) or not d["name"]:
            raise ModelError(f"{where}: key 'name' needs a non-empty string, got {d['name']!r}")
        kw["name"] = d["name"]
    if "doc" in d and not isinstance(d["doc"], str):
        raise ModelError(f"{where}: key 'doc' needs a string")
    for key in ("speed_ref_mps", "turn_ref_deg_s", "accel_ref_mps2"):
        if key in d:
            kw[key] = _number(where, key, d[key])
    for group in ("white", "bias"):
        if group in d:
            for act, v in _table(where, group, d[group], _ACTIVITIES).items():
                kw[f"{group}_{act}"] = _six(where, f"{group}.{act}", v)
    if "moving_gm" in d:
        gm = _table(where, "moving_gm", d["moving_gm"], ("sigma", "tau_s"))
        if "sigma" in gm:
            if "tau_s" not in gm:
                raise ModelError(f"{where}: key 'moving_gm.tau_s' is needed with 'moving_gm.sigma' (6 values > 0 s)")
            kw["moving_gm_sigma"] = _six(where, "moving_gm.sigma", gm["sigma"])
            kw["moving_gm_tau_s"] = _six(where, "moving_gm.tau_s", gm["tau_s"], positive=True)
    if "departure_step" in d:
        kw["departure_step"] = _six(where, "departure_step", d["departure_step"])
    if "warmup" in d:
        wu = _table(where, "warmup", d["warmup"], ("amplitude", "tau_s"))
        if "amplitude" in wu:
            if "tau_s" not in wu:
                raise ModelError(f"{where}: key 'warmup.tau_s' is needed with 'warmup.amplitude' (a number > 0 s)")
            amp = wu["amplitude"]
            ok = isinstance(amp, list) and len(amp) == _N and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in amp)
            if not ok:
                raise ModelError(f"{where}: key 'warmup.amplitude' needs a list of {_N} numbers (gyro x, y, z, "
                                 f"accel x, y, z; SI units), got {amp!r}")
            kw["warmup_amplitude"] = tuple(float(x) for x in amp)
            kw["warmup_tau_s"] = _number(where, "warmup.tau_s", wu["tau_s"])
    return MotionNoise(**kw)


def load_law(path: str | Path) -> MotionNoise:
    """A motion law from a JSON file of the law-file schema (module docstring).

    Raises
    ------
    ModelError
        One line naming the file and the bad key (or the JSON error), e.g. from ``--motion-noise FILE``.
    """
    p = Path(path)
    try:
        d = json.loads(p.read_text())
    except OSError as exc:
        raise ModelError(f"motion law {p}: cannot read it ({exc.strerror or exc})") from None
    except json.JSONDecodeError as exc:
        raise ModelError(f"motion law {p}: not JSON ({exc.msg}, line {exc.lineno})") from None
    law = law_from_dict(d, f"motion law {p}")
    return law if "name" in d else MotionNoise(**{**asdict(law), "name": p.stem})


def _shipped() -> dict[str, MotionNoise]:
    folder = resources.files("imunoise.sim").joinpath(LAW_DIR)
    out = {}
    # the two presets first (the names of the earlier preset list), then the others by name
    for f in sorted(folder.iterdir(), key=lambda f: (f.name not in ("none.json", "drive0708.json"),
                                                      f.name != "none.json", f.name)):
        if f.name.endswith(".json"):
            out[f.name[:-5]] = law_from_dict(json.loads(f.read_text()), f"motion law {f.name}")
    return out


LAWS: dict[str, MotionNoise] = _shipped()
NONE = LAWS["none"]

# Calibrated on the experiments' default scenario (paper IMU preset, 600 s drives with 4 stops) by
# scripts/calibrate_motion_noise.py against the real drive's ratio (std of 10 s means while moving) / (static
# ADEV at 10 s) per gyro axis: 0.91 / 3.9 / 20.5. Gyro x gets no bias amplification: the static model alone
# already gives a larger ratio there (its rate random walk accumulates over a drive). White noise: ×3 on the
# gyros and ×7 on the accelerometers at speed, the earlier simulator's vibration (0.1 °/s and 0.05 m/s² per
# sample at ≥ 3 m/s) against the white σ of the paper/mems presets. The real drive's regressions of the
# errors on speed and |ω_z| explain little (R² 0.08–0.30), so the preset is a moving/at-rest switch ramped
# by speed; the turn terms are 0. Shipped as laws/drive0708.json.
DRIVE0708 = LAWS["drive0708"]

MOTION_PRESETS: dict[str, MotionNoise] = {"none": NONE, "drive0708": DRIVE0708}
DEFAULT_MOTION = "drive0708"


def resolve_motion(spec: str | Path | MotionNoise) -> MotionNoise:
    """A :class:`MotionNoise` from a shipped law's name (:data:`LAWS`, e.g. the presets ``none`` and
    ``drive0708``), a path to a law file (:func:`load_law`: anything ending in ``.json`` or an existing file),
    or a MotionNoise (returned as is).

    Raises
    ------
    ModelError
        For an unknown name (listing the shipped laws), a malformed file (naming the key) or another type.
    """
    if isinstance(spec, MotionNoise):
        return spec
    if isinstance(spec, (str, Path)):
        if isinstance(spec, str) and spec.lower() in LAWS:
            return LAWS[spec.lower()]
        if str(spec).lower().endswith(".json") or Path(spec).is_file():
            return load_law(spec)
    raise ModelError(f"unknown motion-noise preset {spec!r}; choose one of {', '.join(LAWS)} or give a law "
                     "file (FILE.json)")


def motion_arg(spec: str) -> str:
    """The value of ``--motion-noise`` to carry to the workers: a shipped law's name as is, a law file as its
    absolute path (loaded and checked here, so a malformed file fails before any run).

    Raises
    ------
    ModelError
        As :func:`resolve_motion`.
    """
    resolve_motion(spec)
    return spec.lower() if spec.lower() in LAWS else str(Path(spec).resolve())

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
