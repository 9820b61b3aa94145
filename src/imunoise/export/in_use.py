"""In-use values in an export: the (N, K) a filter should carry while the vehicle moves, from the in-motion part of
a model file (``ImuModel.in_motion``; docs/guide/theory.rst, 'Interfaces'; :mod:`imunoise.export`).

The static pair (N, K) of :func:`imunoise.export.sensor_noise` describes the stops. The in-motion part holds per
axis the **in-use / static factor** of the exported N (``factor_N``) and of the exported K (``factor_K``), each
with its 95 % interval, estimated from whole GNSS-aided drives. The in-use pair of an axis is the static pair
times its factors (N_use = factor_N · N, K_use = factor_K · K); a sensor's three axes are combined as the static
ones are (maximum or root mean square), so the written factor of a sensor is N_use / N of the combined values,
and its interval the same combination of each axis's interval end (the combination is increasing in every axis,
so the ends bound the combined factor). An axis whose ``factor_N`` is missing takes its ``white_factor`` (the
σ-scale of the white noise while moving, the same factor on a white-noise density).

What the drives could not separate is a **bound** (``in_motion.bounds[axis]``: what, upper, reason), never a
number: that axis writes its static value and the comment says the in-use value is bounded, with the bound and
its reason. An axis with neither a factor nor a bound writes its static value too, and the comment says so.

``--noise in-use`` (the default) writes the in-use pair when the model has an in-motion part; ``--noise static``
writes the static pair. A model without the part exports exactly as before: :func:`apply_noise` returns the
static :class:`~imunoise.export.noise.SensorNoise` objects themselves, and every comment helper here returns an
empty string for them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.export.noise import SensorNoise, format_float
from imunoise.io.imu_input import sensor_of

__all__ = ["NOISE_CHOICES", "Factor", "InUse", "InUseNoise", "in_motion_part", "apply_noise", "in_use_comment",
           "in_use_header"]

NOISE_CHOICES = ("in-use", "static")
_SLOT = {"N": ("factor_N", "white_factor"), "K": ("factor_K",)}
_BOUND_SLOT = {"white": "N", "white_factor": "N", "factor_N": "N", "N": "N",
               "bias": "K", "factor_K": "K", "K": "K"}


@dataclass(frozen=True)
class Factor:
    """An in-use / static factor with its 95 % interval."""

    value: float
    lo: float
    hi: float

    @classmethod
    def read(cls, d: Any, where: str) -> Factor:
        """``{"value": v, "ci95": [lo, hi]}`` (the interval may be absent: then [v, v])."""
        try:
            v = float(d["value"])
            lo, hi = (float(x) for x in d.get("ci95") or (v, v))
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelError(f"{where}: an in-use factor needs 'value' and 'ci95': [lo, hi], got {d!r}") from exc
        if not (math.isfinite(v) and v > 0 and 0 < lo <= v <= hi and math.isfinite(hi)):
            raise ModelError(f"{where}: in-use factor {v} with 95 % CI [{lo}, {hi}]: need finite 0 < lo <= value <= hi")
        return cls(v, lo, hi)

    def text(self) -> str:
        one = "; the interval holds 1: no evidence it differs while moving" if self.lo <= 1.0 <= self.hi else ""
        return f"{self.value:.3g}x static (95 % CI {self.lo:.3g}-{self.hi:.3g}{one})"


@dataclass(frozen=True)
class InUse:
    """The in-use side of one sensor's pair: ``static`` the static SensorNoise (as written with ``--noise static``),
    the combined factors of N and K (None when no axis has one), and per slot the axes left at their static value
    with why (``"bounded: ..."``, a wander without a K factor, or ``"no in-motion estimate"``)."""

    static: SensorNoise
    factor_N: Factor | None
    factor_K: Factor | None
    static_axes: Mapping[str, tuple[tuple[str, str], ...]]
    evidence: str = ""


@dataclass(frozen=True)
class InUseNoise(SensorNoise):
    """A SensorNoise whose written pair is the in-use one (:class:`InUse` says how it follows from the static)."""

    in_use: InUse | None = None

    def to_dict(self) -> dict[str, Any]:
        d = super().to_dict()
        u = self.in_use
        if u is not None:
            d["in_use"] = {
                "written": "in-use",
                "static_noise_density": u.static.noise_density, "static_random_walk": u.static.random_walk,
                **{f"factor_{s}": (None if f is None else {"value": f.value, "ci95": [f.lo, f.hi]})
                   for s, f in (("N", u.factor_N), ("K", u.factor_K))},
                "static_axes": {s: [list(x) for x in v] for s, v in u.static_axes.items()},
                "evidence": u.evidence,
            }
        return d


def in_motion_part(model: Any) -> dict[str, Any] | None:
    """The model's in-motion part as the file's dict (``in_motion``), or None (a single fit, or a model without
    the part)."""
    part = getattr(model, "in_motion", None)
    if part is None:
        return None
    if hasattr(part, "to_dict"):
        part = part.to_dict()
    if not isinstance(part, Mapping):
        raise ModelError(f"the model's in-motion part is not an object ({type(part).__name__})")
    return dict(part)


def _evidence_text(ev: Mapping[str, Any]) -> str:
    bits = []
    if ev.get("drives"):
        bits.append(f"{len(ev['drives'])} drive(s)")
    if ev.get("hours_moving") is not None:
        bits.append(f"{float(ev['hours_moving']):.3g} h moving")
    if ev.get("gnss_sigma_m") is not None:
        bits.append(f"GNSS sigma {float(ev['gnss_sigma_m']):.3g} m")
    if ev.get("method"):
        bits.append(str(ev["method"]))
    return ", ".join(bits)


def _axis_factor(part: Mapping[str, Any], axis: str, slot: str) -> tuple[Factor | None, str]:
    """The factor of ``slot`` ("N" or "K") of ``axis``, or (None, why it stays static). A slot whose value is
    null is not identified; ``white_factor`` stands for a missing ``factor_N`` only when it has an interval."""
    ax = (part.get("axes") or {}).get(axis) or {}
    for key in _SLOT[slot]:
        d = ax.get(key)
        if isinstance(d, Mapping) and d.get("value") is not None and (key == _SLOT[slot][0] or d.get("ci95")):
            return Factor.read(d, f"in_motion.axes.{axis}.{key}"), ""
        if key == _SLOT[slot][0] and key in ax:
            break  # the factor is there and null: not identified (its bound, if any, says why)
    b = (part.get("bounds") or {}).get(axis)
    if isinstance(b, Mapping) and _BOUND_SLOT.get(str(b.get("what", "bias")), "K") == slot:
        what, up = str(b.get("what", "bias")), b.get("upper")
        unit = "rad/s" if sensor_of(axis, None) == "gyro" else "m/s^2"
        up_text = f"{what} <= {float(up):.4g} {unit}" if up is not None else f"{what} not even bounded"
        return None, f"bounded ({up_text}: {b.get('reason') or 'no reason recorded'})"
    wander = ax.get("bias") if slot == "K" else None
    if isinstance(wander, Mapping) and wander.get("model") in ("gm", "rw"):  # a wander, but no static K to scale
        return None, (f"bias wander while moving {_wander_text(wander, axis)} has no K factor: the static model "
                      "has no random walk on this axis to scale; see the model file's in_motion part")
    return None, "no in-motion estimate"


def _wander_text(w: Mapping[str, Any], axis: str) -> str:
    unit = "rad/s" if sensor_of(axis, None) == "gyro" else "m/s^2"
    if w.get("model") == "gm":
        return f"GM sigma {float(w['sigma']):.4g} {unit}, tau {float(w['tau_s']):.4g} s"
    return f"RW k {float(w['k']):.4g} {unit}/sqrt(s)"


def _combine(values: np.ndarray, how: str) -> float:
    return float(values.max()) if how == "max" else float(np.sqrt(np.mean(values**2)))


def _in_use_sensor(sn: SensorNoise, part: Mapping[str, Any]) -> InUseNoise:
    stat = {"N": np.array([a.N for a in sn.axes]), "K": np.array([a.K for a in sn.axes])}
    raw = {"N": sn.raw_noise_density, "K": sn.raw_random_walk}
    use, factors, static_axes = {}, {}, {}
    for slot in ("N", "K"):
        v, lo, hi, keep, found = [], [], [], [], False
        for a, s in zip(sn.axes, stat[slot], strict=True):
            f, why = _axis_factor(part, a.axis, slot)
            found |= f is not None
            f = f or Factor(1.0, 1.0, 1.0)
            v.append(s * f.value)
            lo.append(s * f.lo)
            hi.append(s * f.hi)
            if why:
                keep.append((a.axis, why))
        use[slot] = _combine(np.array(v), sn.combine)
        factors[slot] = (Factor(use[slot] / raw[slot], _combine(np.array(lo), sn.combine) / raw[slot],
                                _combine(np.array(hi), sn.combine) / raw[slot]) if found else None)
        static_axes[slot] = tuple(keep)
    info = InUse(sn, factors["N"], factors["K"], static_axes, _evidence_text(part.get("evidence") or {}))
    fields = {k: getattr(sn, k) for k in SensorNoise.__dataclass_fields__}
    fields.update(noise_density=use["N"] * sn.inflate_white, random_walk=use["K"] * sn.inflate_rw,
                  raw_noise_density=use["N"], raw_random_walk=use["K"])
    return InUseNoise(**fields, in_use=info)


def apply_noise(model: Any, sensors: dict[str, SensorNoise], noise: str = "in-use") -> dict[str, SensorNoise]:
    """The sensors' pairs as ``noise`` asks: ``"in-use"`` → the in-use pair where the model has an in-motion
    part (:class:`InUseNoise`), else the static ``sensors`` unchanged; ``"static"`` → ``sensors`` unchanged.

    Parameters
    ----------
    model : ImuModel or GMWMFit
        The exported model (its ``in_motion`` part, if any).
    sensors : dict
        The static pairs per sensor (:func:`imunoise.export.formats.model_sensors`).
    noise : {"in-use", "static"}
        ``--noise``.

    Returns
    -------
    dict
        Per sensor the SensorNoise to write.
    """
    if noise not in NOISE_CHOICES:
        raise ModelError(f"--noise must be one of {', '.join(NOISE_CHOICES)}, got {noise!r}")
    part = in_motion_part(model)
    if noise == "static" or part is None:
        return sensors
    return {s: _in_use_sensor(sn, part) for s, sn in sensors.items()}


def in_use_comment(sn: SensorNoise, which: str, static_value: float | None = None) -> str:
    """The in-use text of one written key (``which`` "N" or "K"), starting with ``"; "``, or ``""`` for a static
    pair: the factor with its interval and the static value (``static_value``: that key's static value in the
    tool's own convention; default the static density), and the axes left static with why."""
    if not isinstance(sn, InUseNoise) or sn.in_use is None:
        return ""
    u = sn.in_use
    f = u.factor_N if which == "N" else u.factor_K
    if static_value is None:
        static_value = u.static.noise_density if which == "N" else u.static.random_walk
    out = f"; in-use {which} = {f.text()}" if f is not None else f"; in-use {which} = static"
    out += f"; static {format_float(static_value)} (--noise static)"
    if kept := u.static_axes[which]:
        out += "; static value kept on " + ", ".join(f"{ax} ({why})" for ax, why in kept)
    return out


def in_use_header(sensors: Mapping[str, SensorNoise]) -> list[str]:
    """The header lines of an in-use export (empty for a static one)."""
    used = [sn for sn in sensors.values() if isinstance(sn, InUseNoise) and sn.in_use is not None]
    if not used:
        return []
    ev = next((sn.in_use.evidence for sn in used if sn.in_use.evidence), "")
    return [
        "# IN-USE values: the pair below is what the filter should carry while the vehicle moves: the static pair",
        "#   of the stops (per axis above) times the in-use/static factor estimated from whole GNSS-aided drives",
        f"#   ({ev or 'evidence not recorded'}); each key says the factor with its 95 % interval and the static value.",
        "#   A factor of 2 means the noise while moving is twice the stops' (not a margin). Static values:",
        "#   imunoise export MODEL --noise static.",
    ]
