"""Checks of the arguments every estimator shares: the sample rate and the data unit
(docs/guide/theory.rst, 'Conventions')."""

from __future__ import annotations

import math
import numbers
from typing import Any

from imunoise.errors import DataError, UnitError

__all__ = ["check_freq", "check_unit"]


def check_freq(freq: Any, name: str = "freq") -> float:
    """The sample rate as a float, or a :class:`DataError` saying how to give it (docs/guide/theory.rst, 'Conventions').

    Parameters
    ----------
    freq
        Sample rate in Hz: a real number (int, float, NumPy scalar), finite and > 0. Strings, ``None``
        and booleans are refused rather than guessed: the CLI's ``--freq`` is parsed as a float, the
        Python API takes the number itself.
    name
        Argument name used in the message.

    Returns
    -------
    float
        ``float(freq)``.
    """
    if freq is None:
        raise DataError(f"{name} is None; give the sample rate in Hz, e.g. {name}=100.0")
    if isinstance(freq, bool) or not isinstance(freq, numbers.Real):
        raise DataError(
            f"{name} must be a number in Hz, got {freq!r} ({type(freq).__name__}); e.g. {name}=100.0"
            + (f" instead of {name}={freq!r}" if isinstance(freq, str) else "")
        )
    value = float(freq)
    if not (math.isfinite(value) and value > 0):
        raise DataError(f"{name} must be a finite rate > 0 Hz, got {freq!r}")
    return value


def check_unit(unit: Any) -> str:
    """``unit`` if it names a unit the readers know (docs/guide/theory.rst, 'Conventions'; same table as the CLI's
    ``--units``).

    ``"u"`` means "unspecified" (the default of the estimators). Anything else must be a unit of
    :data:`imunoise.units.UNITS` (e.g. ``"rad/s"``, ``"m/s²"``, ``"deg/h"``); an unknown name raises the
    CLI's :class:`UnitError` listing the known ones. The unit only labels results: the estimators do not
    convert data (convert with :func:`imunoise.units.to_si` first).

    Parameters
    ----------
    unit
        ``"u"`` or a unit name of :data:`imunoise.units.UNITS`.

    Returns
    -------
    str
        ``unit`` unchanged.
    """
    if not isinstance(unit, str):
        raise UnitError(f"unit must be a string such as 'rad/s' or 'm/s²', got {unit!r}")
    if unit != "u":
        from imunoise.units import quantity_of

        quantity_of(unit)  # raises UnitError("unknown unit ...; use one of: ...")
    return unit
