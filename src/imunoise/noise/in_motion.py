"""The in-motion part of an IMU model file (docs/guide/theory.rst, 'In-use noise'): what the filter sees while the
vehicle moves, beside the static part fitted on the stops.

JSON layout (the ``"in_motion"`` key of :class:`imunoise.noise.imu_model.ImuModel`; absent: the model is the
static part alone and behaves exactly as before)::

    "in_motion": {
      "axes": {"gyro_y": {
          "white_factor": {"value": 2.1, "ci95": [1.8, 2.5]},
          "bias": {"model": "gm", "sigma": 5.8e-4, "tau_s": 60.0, "ci95": {"sigma": [..], "tau_s": [..]}},
          "factor_N": {"value": .., "ci95": [..]}, "factor_K": {"value": .., "ci95": [..]}}, ...},
      "bounds": {"accel_x": {"what": "bias", "upper": .., "reason": "..."}},
      "evidence": {"drives": [...], "hours_moving": .., "gnss_sigma_m": .., "method": "...", "freq_hz": ..}}

``white_factor`` multiplies the static white-noise density N while moving (a σ scale: the white PSD is
multiplied by its square). ``bias`` is the bias wander that evolves while moving only and is frozen at stops:
``"gm"`` (Gauss–Markov, ``sigma`` in the axis' unit, ``tau_s``), ``"rw"`` (random walk, ``k`` in unit/√s) or
``"none"``. ``factor_N`` and ``factor_K`` are the in-use / static factors of the exported (N, K)
(:meth:`AxisInMotion.equivalent_pair`). A value the data do not identify is ``null`` with an entry in
``bounds`` (an upper bound and the reason), never a number. Units: rad/s for gyros, m/s² for accelerometers.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from imunoise.errors import ModelError
from imunoise.imu import AXES

__all__ = ["Interval", "BiasWander", "AxisInMotion", "Bound", "InMotionPart", "gm_equivalent_k", "walk_tau_s"]

BIAS_MODELS = ("gm", "rw", "none")
WALK_TAU_NO_EVIDENCE_S = 1e6
"""τ [s] of a random walk's Gauss–Markov when the part does not say how long its drives moved."""


def walk_tau_s(hours_moving: float | None) -> float:
    """The τ [s] of the Gauss–Markov that carries a bias random walk in the filter: the longest τ the in-motion
    estimate searches, 3 × the moving time of the drives it saw and at least 20 s (the estimate reports a walk
    when τ reaches that bound, so the filter uses the walk in the form it was estimated in). Without that
    evidence (``None``: a hand-written part), :data:`WALK_TAU_NO_EVIDENCE_S`.

    Why not a near-infinite τ: the moving state starts at its stationary variance σ² = k²τ/2. With τ = 1e6 s a
    gyro walk of k = 8e-5 rad/s/√s starts at 3 °/s (1σ); on a simulated vehicle the GNSS-aided run then took
    heading errors for gyro bias and diverged (33 m aided horizontal RMS against 1.7 m with τ of the order of
    the moving time: docs/evidence/in_use_ceiling.md, 'One vehicle')."""
    if hours_moving is None or not math.isfinite(float(hours_moving)) or hours_moving <= 0:
        return WALK_TAU_NO_EVIDENCE_S
    return max(3600.0 * float(hours_moving) * 3.0, 20.0)


def gm_equivalent_k(sigma: float, tau_s: float) -> float:
    """The random-walk coefficient K [unit/√s] of a Gauss–Markov (σ, τ) at scales ≪ τ: its driving noise
    density √(2σ²/τ) (the process is b' = −b/τ + w, E[w²] = 2σ²/τ per second)."""
    return math.sqrt(2.0 * sigma * sigma / tau_s) if sigma > 0 and tau_s > 0 else 0.0


def _ci(v: Any) -> tuple[float, float] | None:
    if v is None:
        return None
    lo, hi = v
    return (float(lo), float(hi))


def _num(v: Any) -> float | None:
    return None if v is None else float(v)


@dataclass(frozen=True)
class Interval:
    """A value with its 95 % interval (``value`` None: not identified, see the part's bounds)."""

    value: float | None
    ci95: tuple[float, float] | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"value": self.value, "ci95": None if self.ci95 is None else list(self.ci95)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> Interval:
        d = d or {}
        return cls(_num(d.get("value")), _ci(d.get("ci95")))

    def covers(self, x: float) -> bool:
        """Whether the interval contains ``x`` (False without an interval)."""
        return self.ci95 is not None and self.ci95[0] <= x <= self.ci95[1]


@dataclass(frozen=True)
class BiasWander:
    """Bias wander while moving (frozen at stops): ``model`` "gm" (``sigma``, ``tau_s``), "rw" (``k``) or "none";
    ``ci95`` the intervals of its parameters by name."""

    model: str = "none"
    sigma: float | None = None
    tau_s: float | None = None
    k: float | None = None
    ci95: dict[str, tuple[float, float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.model not in BIAS_MODELS:
            raise ModelError(f"in_motion bias model {self.model!r}: expected one of {', '.join(BIAS_MODELS)}")

    def equivalent_k(self) -> float:
        """K [unit/√s] of the wander (:func:`gm_equivalent_k` for a GM, ``k`` for a RW, 0 for none or unknown)."""
        if self.model == "gm" and self.sigma is not None and self.tau_s is not None:
            return gm_equivalent_k(self.sigma, self.tau_s)
        if self.model == "rw" and self.k is not None:
            return float(self.k)
        return 0.0

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"model": self.model}
        if self.model == "gm":
            d.update(sigma=self.sigma, tau_s=self.tau_s)
        elif self.model == "rw":
            d["k"] = self.k
        d["ci95"] = {k: list(v) for k, v in self.ci95.items()}
        return d

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> BiasWander:
        d = d or {}
        ci = {str(k): _ci(v) for k, v in (d.get("ci95") or {}).items() if v is not None}
        return cls(str(d.get("model", "none")), _num(d.get("sigma")), _num(d.get("tau_s")), _num(d.get("k")),
                   ci)  # type: ignore[arg-type]


@dataclass(frozen=True)
class AxisInMotion:
    """One axis' in-motion noise: the white factor, the bias wander and the factors of the exported (N, K)."""

    white_factor: Interval = Interval(1.0)
    bias: BiasWander = BiasWander()
    factor_N: Interval = Interval(None)
    factor_K: Interval = Interval(None)

    def equivalent_pair(self, n_static: float, k_static: float) -> tuple[float, float]:
        """The in-use (N, K) [unit/√Hz, unit/√s] from the static pair: N × the white factor (1 when not
        identified), K combined with the wander's equivalent K in quadrature √(K² + K_wander²)."""
        wf = self.white_factor.value if self.white_factor.value is not None else 1.0
        return n_static * wf, math.hypot(k_static, self.bias.equivalent_k())

    def to_dict(self) -> dict[str, Any]:
        return {"white_factor": self.white_factor.to_dict(), "bias": self.bias.to_dict(),
                "factor_N": self.factor_N.to_dict(), "factor_K": self.factor_K.to_dict()}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> AxisInMotion:
        return cls(Interval.from_dict(d.get("white_factor")), BiasWander.from_dict(d.get("bias")),
                   Interval.from_dict(d.get("factor_N")), Interval.from_dict(d.get("factor_K")))


@dataclass(frozen=True)
class Bound:
    """What the data cannot separate on one axis: ``what`` ("white" or "bias"), an ``upper`` bound (in the
    parameter's unit; None when not even bounded) and the ``reason``."""

    what: str
    upper: float | None
    reason: str

    def to_dict(self) -> dict[str, Any]:
        return {"what": self.what, "upper": self.upper, "reason": self.reason}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Bound:
        return cls(str(d.get("what", "")), _num(d.get("upper")), str(d.get("reason", "")))


@dataclass(frozen=True)
class InMotionPart:
    """The in-motion part of a model file (module docstring): per axis an :class:`AxisInMotion`, the
    :class:`Bound` s of what the data cannot separate, and the evidence behind it."""

    axes: dict[str, AxisInMotion]
    bounds: dict[str, Bound] = field(default_factory=dict)
    evidence: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        bad = [a for a in self.axes if a not in AXES]
        if bad:
            raise ModelError(f"in_motion axes {bad}: expected names among {', '.join(AXES)}")

    def axis(self, name: str) -> AxisInMotion:
        """The axis' in-motion noise (an axis not given: factor 1, no wander)."""
        return self.axes.get(name, AxisInMotion())

    def white_factors(self) -> list[float]:
        """The six white factors (1 where not identified)."""
        return [self.axis(a).white_factor.value or 1.0 for a in AXES]

    def moving_gm(self) -> tuple[list[float], list[float]]:
        """The six moving Gauss–Markov (σ, τ [s]) of the filter (σ = 0 where none; a random walk k as a GM with
        τ = :func:`walk_tau_s` of the evidence's moving hours and σ = k√(τ/2), the same driving noise)."""
        sig, tau = [], []
        t_walk = walk_tau_s(self.evidence.get("hours_moving"))
        for a in AXES:
            b = self.axis(a).bias
            if b.model == "gm" and b.sigma and b.tau_s:
                sig.append(float(b.sigma))
                tau.append(float(b.tau_s))
            elif b.model == "rw" and b.k:
                sig.append(float(b.k) * math.sqrt(t_walk / 2.0))
                tau.append(t_walk)
            else:
                sig.append(0.0)
                tau.append(60.0)
        return sig, tau

    def to_dict(self) -> dict[str, Any]:
        return {"axes": {a: self.axes[a].to_dict() for a in AXES if a in self.axes},
                "bounds": {a: b.to_dict() for a, b in self.bounds.items()}, "evidence": dict(self.evidence)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> InMotionPart:
        if not isinstance(d, Mapping) or not isinstance(d.get("axes"), Mapping):
            raise ModelError("in_motion: expected an object with 'axes' (per axis white_factor and bias)")
        return cls({str(a): AxisInMotion.from_dict(v) for a, v in d["axes"].items()},
                   {str(a): Bound.from_dict(v) for a, v in (d.get("bounds") or {}).items()},
                   dict(d.get("evidence") or {}))
