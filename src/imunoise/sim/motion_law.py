"""The motion law's coefficients (:class:`MotionNoise`): per-axis multipliers of the white and bias-process noise
by speed, turn and acceleration activity, and the additive terms (moving Gauss–Markov, departure steps, warm-up);
the law's equations are in :mod:`imunoise.sim.motion`, its files in :mod:`imunoise.sim.law_files`."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.imu import AXES
from imunoise.sim.law_terms import departure_steps, moving_gauss_markov, warmup_bias

__all__ = ["MotionNoise"]

_N = len(AXES)
_ZERO = (0.0,) * _N


@dataclass(frozen=True)
class MotionNoise:
    """Per-axis motion law (:mod:`imunoise.sim.motion`): multipliers of the white-noise σ (``white_*``) and of the
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
        """(m^w, m^b), each (n, 6): the law of :mod:`imunoise.sim.motion` at speeds [m/s], turn rates [rad/s] and
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
