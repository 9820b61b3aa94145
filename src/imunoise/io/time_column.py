"""Which column of an IMU table holds the time stamps, and in which unit
(docs/guide/theory.rst, 'Conventions' and 'Interfaces').

**By name.** Without ``--time-column`` a column named like a time stamp is taken as the time, never
fitted as a sensor: ``t``, ``time``, ``times``, ``timestamp``, ``stamp``, ``ts``, ``sec``, ``seconds``,
``header.stamp`` (also ``%time``, ``field.header.stamp`` of ``rostopic echo -p``, ``header_stamp``), with an
optional unit suffix (``time_ns``, ``timestamp [us]``, ``t(s)``) that also gives the unit.

**Unit from the spacing.** A noise model's densities scale with √f, so a stamp unit wrong by 10⁹ is a model
wrong by 3·10⁴. The median step between stamps, read in a unit, gives a rate; IMU rates lie in
:data:`IMU_RATES` (1 Hz – 100 kHz), most in :data:`TYPICAL_IMU_RATES` (10 Hz – 10 kHz, one factor 1000 wide,
so at most one of s/ms/µs/ns puts a step inside it). :func:`infer_time_unit`:

* unit not given: seconds when they give an IMU rate, else the one unit that gives a typical rate (said in
  a warning kept with the output); two candidates and no typical one: refused, asking for ``--time-unit``;
* unit given: used, unless it gives no IMU rate while another unit gives a typical one: then refused with
  that unit in the message (``--time-unit ns``), rather than fitting at 2·10⁻⁷ Hz.

What counts as given (:func:`stated_time_unit`): a unit passed by the caller, else the unit in the column's
name. For a column found by its name (no ``--time-column``), ``s`` — the default of ``--time-unit`` — is
not a statement about that column: its unit comes from the name or the spacing.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from imunoise.errors import DataError
from imunoise.units import TIME_UNITS

__all__ = [
    "IMU_RATES",
    "TYPICAL_IMU_RATES",
    "TIME_NAMES",
    "find_time_column",
    "infer_time_unit",
    "stated_time_unit",
    "unit_in_name",
]

IMU_RATES = (1.0, 1e5)
"""Hz: the rates an IMU log can have; outside them the stamp unit is doubted."""

TYPICAL_IMU_RATES = (10.0, 1e4)
"""Hz: the rates almost every IMU logs at (one factor 1000: the step between time units)."""

TIME_NAMES = ("t", "time", "times", "timestamp", "timestamps", "stamp", "stamps", "ts", "sec", "secs", "seconds",
              "header.stamp", "header_stamp", "time_stamp", "field.header.stamp", "%time", "epoch")
"""Column names taken as the time stamps (lower case, unit suffix removed)."""

_UNIT_SUFFIX = re.compile(r"^(?P<name>.*?)[\s_\-]*[\[(]?(?P<unit>s|ms|us|µs|ns)[\])]?$")


def _split_unit(name: str) -> tuple[str, str | None]:
    low = name.strip().lower()
    if low in TIME_NAMES:
        return low, None
    m = _UNIT_SUFFIX.match(low)
    if m and m.group("name") in TIME_NAMES:
        return m.group("name"), m.group("unit")
    return low, None


def unit_in_name(name: str) -> str | None:
    """The time unit a time column's name states (``time_ns`` -> ``"ns"``), else None."""
    base, unit = _split_unit(name)
    return unit if base in TIME_NAMES else None


def stated_time_unit(time_unit: str | None, name: str, found_by_name: bool) -> str | None:
    """The unit stated for time column ``name``: ``time_unit``, except the default ``"s"`` for a column
    found by its name; else the unit in the name (``time_ns``); else None (inferred)."""
    if time_unit is not None and not (found_by_name and time_unit == "s"):
        return time_unit
    return unit_in_name(name)


def find_time_column(names: Sequence[str]) -> int | None:
    """Index of the one column named like a time stamp (:data:`TIME_NAMES`), else None (none or several)."""
    hits = [i for i, n in enumerate(names) if _split_unit(n)[0] in TIME_NAMES]
    return hits[0] if len(hits) == 1 else None


def _rate(step: float, unit: str) -> float:
    return 1.0 / (step * TIME_UNITS[unit])


def infer_time_unit(step: float, given: str | None, source: str) -> tuple[str, str | None]:
    """The unit of stamps whose median step is ``step`` (in the file's numbers), and a note when it was
    inferred (module docstring for the rule). Raises :class:`DataError` naming ``--time-unit``.

    Returns
    -------
    (unit, note)
        ``note`` is None when the unit was given or is seconds.
    """
    if not step > 0:
        return given or "s", None
    lo, hi = IMU_RATES
    tlo, thi = TYPICAL_IMU_RATES
    units = ("s", "ms", "us", "ns")
    typical = [u for u in units if tlo <= _rate(step, u) <= thi]
    if given is not None:
        if lo <= _rate(step, given) <= hi or not typical or typical == [given]:
            return given, None
        u = typical[0]
        raise DataError(
            f"{source}: a step of {step:.4g} {given} between stamps is {_rate(step, given):.3g} Hz, not an IMU "
            f"rate; in {u} it is {_rate(step, u):.4g} Hz: give --time-unit {u}"
        )
    if lo <= _rate(step, "s") <= hi:
        return "s", None
    if len(typical) == 1:
        u = typical[0]
        return u, (
            f"{source}: time unit taken as {u} from the stamp spacing ({step:.4g} per sample = "
            f"{_rate(step, u):.4g} Hz); give --time-unit to say otherwise"
        )
    plausible = [u for u in units if lo <= _rate(step, u) <= hi]
    if plausible:
        options = " or ".join(f"{_rate(step, u):.3g} Hz in {u}" for u in plausible)
        raise DataError(f"{source}: a step of {step:.4g} between stamps is {options}; give --time-unit")
    return "s", None
