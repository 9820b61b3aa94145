"""Physical units at the boundary (docs/guide/theory.rst, 'Conventions'): readers convert to SI, writers say what they
wrote.

Inside imunoise everything is SI: rad/s for angular rate, m/s² for specific force, rad and m/s for
increments, s for time. Conversions are plain multiplicative factors to the SI unit of the quantity.
"""

from __future__ import annotations

import math

import numpy as np

from imunoise.errors import UnitError

__all__ = ["G0", "to_si", "si_unit", "UNITS", "TIME_UNITS", "quantity_of", "time_to_seconds", "required_freq"]

G0 = 9.80665  # standard gravity, m/s² per g

# unit -> (quantity, factor to SI)
UNITS: dict[str, tuple[str, float]] = {
    "rad/s": ("rate", 1.0),
    "deg/s": ("rate", math.pi / 180.0),
    "deg/h": ("rate", math.pi / 180.0 / 3600.0),
    "mrad/s": ("rate", 1e-3),
    "m/s2": ("accel", 1.0),
    "m/s^2": ("accel", 1.0),
    "m/s²": ("accel", 1.0),
    "g": ("accel", G0),
    "mg": ("accel", 1e-3 * G0),
    "ug": ("accel", 1e-6 * G0),
    "µg": ("accel", 1e-6 * G0),
    "rad": ("angle_increment", 1.0),
    "deg": ("angle_increment", math.pi / 180.0),
    "m/s": ("velocity_increment", 1.0),
    "1": ("dimensionless", 1.0),
}

SI_UNIT = {
    "rate": "rad/s",
    "accel": "m/s²",
    "angle_increment": "rad",
    "velocity_increment": "m/s",
    "dimensionless": "1",
}

TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "ns": 1e-9}


def _lookup(unit: str) -> tuple[str, float]:
    key = unit.strip().replace(" ", "")
    if key in UNITS:
        return UNITS[key]
    low = key.lower()
    for name, val in UNITS.items():
        if name.lower() == low:
            return val
    raise UnitError(f"unknown unit {unit!r}; use one of: {', '.join(sorted(set(UNITS)))}")


def quantity_of(unit: str) -> str:
    """'rate', 'accel', 'angle_increment', 'velocity_increment' or 'dimensionless'."""
    return _lookup(unit)[0]


def si_unit(unit: str) -> str:
    """The SI unit imunoise uses internally for data given in ``unit``."""
    return SI_UNIT[_lookup(unit)[0]]


def to_si(values: np.ndarray | float, unit: str) -> np.ndarray:
    """Convert data given in ``unit`` to SI (e.g. deg/s -> rad/s, g -> m/s²)."""
    return np.asarray(values, dtype=float) * _lookup(unit)[1]


def time_to_seconds(values: np.ndarray, unit: str) -> np.ndarray:
    if unit not in TIME_UNITS:
        raise UnitError(f"unknown time unit {unit!r}; use one of {', '.join(TIME_UNITS)}")
    return np.asarray(values, dtype=float) * TIME_UNITS[unit]


def required_freq(freq: object, who: str) -> float:
    """The sample rate ``freq`` [Hz] that ``who`` needs, as a float. No rate is assumed: a forgotten one (None)
    is refused with what to write, as are a non-number and a rate that is not finite and > 0 (a fit at an
    assumed 1 Hz would be 100x off at 100 Hz).

    Raises
    ------
    DataError
    """
    from imunoise.errors import DataError

    if freq is None:
        raise DataError(f"{who} needs the sample rate of the data: give freq=HZ (e.g. freq=100.0); none is assumed")
    if isinstance(freq, bool) or not isinstance(freq, (int, float, np.integer, np.floating)):
        raise DataError(f"{who}: freq must be a number in Hz, got {freq!r}; e.g. freq=100.0")
    value = float(freq)
    if not (math.isfinite(value) and value > 0):
        raise DataError(f"{who}: freq must be a finite rate > 0 Hz, got {freq!r}")
    return value
