"""Several columns of a table mapped to output names, each with its unit, converted to SI, with an optional
time column in s/ms/µs/ns (docs/guide/theory.rst, 'Conventions' and 'Interfaces')."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.errors import DataError, UnitError, UnitWarning
from imunoise.io.files import read_text
from imunoise.io.table import Table, read_table
from imunoise.io.time_column import find_time_column, infer_time_unit, stated_time_unit
from imunoise.io.time_stamps import GAP_FACTOR, TimeReport, TimingWarning, clean_time
from imunoise.units import TIME_UNITS, quantity_of, si_unit, time_to_seconds, to_si

__all__ = [
    "Columns",
    "UnitWarning",
    "column_pairs",
    "parse_column_map",
    "read_columns",
    "stamp_step",
    "time_index",
    "unit_for",
]


def unit_for(name: str, column: str, units: str | Mapping[str, str] | None) -> str | None:
    """The unit of output ``name`` read from file column ``column``.

    ``units`` is one unit for every column, or a mapping whose keys are output names (``gyro_x``),
    file column names (``gx``) or sensor groups (``gyro``, ``accel``: every name starting with them).
    """
    if units is None or isinstance(units, str):
        return units
    for key in (name, column):
        if key in units:
            return units[key]
    for key, unit in units.items():
        if name.startswith(key) or column.startswith(key):
            return unit
    return None


@dataclass(frozen=True, eq=False)
class Columns:
    """Columns of a file in SI (time-sorted when there is a time column). ``values[name]``,
    ``unit[name]`` (SI unit), ``source_unit[name]`` (as in the file, ``"u"`` when not given);
    ``t`` in s and ``report`` when a time column was read."""

    path: str
    names: list[str]
    values: dict[str, np.ndarray]
    unit: dict[str, str]
    source_unit: dict[str, str]
    column: dict[str, str]
    t: np.ndarray | None = None
    report: TimeReport | None = None
    extra: dict[str, Any] = field(default_factory=dict)


def parse_column_map(columns: str | Sequence[str | int] | Mapping[str, str | int] | None) -> Any:
    """``"gyro_x=gx,gyro_y=3"`` -> {"gyro_x": "gx", "gyro_y": "3"}; ``"gx,gy"`` -> ["gx", "gy"]. A name given
    twice is refused (the second would silently replace the first)."""
    if columns is None or not isinstance(columns, str):
        return columns
    items = [c.strip() for c in columns.split(",") if c.strip()]
    if items and all("=" in c for c in items):
        pairs = [(k.strip(), v.strip()) for k, v in (c.split("=", 1) for c in items)]
        keys = [k for k, _ in pairs]
        twice = sorted({k for k in keys if keys.count(k) > 1})
        if twice:
            raise DataError(f"--columns {columns!r} names {twice[0]} twice; give each name one column")
        return dict(pairs)
    if any("=" in c for c in items):
        raise DataError(f"--columns {columns!r}: use either all NAME=COLUMN pairs or a plain list of columns")
    return items


def column_pairs(table: Table, cmap: Any, t_idx: int | None) -> list[tuple[str, int]]:
    """(output name, column index) of every selected column (``cmap`` from :func:`parse_column_map`; None:
    every column but the time). One file column read as two names, or the time column read as data, is
    refused: both would fit the same numbers twice (or the clock as a sensor)."""
    if cmap is None:
        pairs = [(c, i) for i, c in enumerate(table.columns) if i != t_idx]
    elif isinstance(cmap, Mapping):
        pairs = [(str(k), table.column_index(v)) for k, v in cmap.items()]
    else:
        pairs = [(table.columns[i], i) for i in (table.column_index(c) for c in cmap)]
    if not pairs:
        raise DataError(f"{table.path}: no data columns selected (columns are: {', '.join(table.columns)})")
    seen: dict[int, str] = {}
    for name, i in pairs:
        if i == t_idx:
            raise DataError(
                f"--columns: column {table.columns[i]!r} of {table.path} is the time column; leave it out of "
                "--columns (or choose another --time-column)"
            )
        if i in seen:
            raise DataError(
                f"--columns maps column {table.columns[i]!r} of {table.path} to both {seen[i]} and {name}; "
                "give each axis its own column"
            )
        seen[i] = name
    return pairs


def time_index(table: Table, time_column: str | int | None, cmap: Any) -> tuple[int | None, bool]:
    """The time column: the one given, else the one named like a time stamp
    (:func:`imunoise.io.time_column.find_time_column`) unless ``cmap`` selects it as data. Returns (index or
    None, found by its name)."""
    if time_column is not None:
        return table.column_index(time_column), False
    i = find_time_column(table.columns)
    if i is None:
        return None, False
    if cmap is not None:
        chosen = cmap.values() if isinstance(cmap, Mapping) else cmap
        try:
            if i in {table.column_index(c) for c in chosen}:
                return None, False
        except DataError:
            pass  # a bad column name is reported by column_pairs, with the time column set or not
    return i, True


def stamp_step(raw: np.ndarray) -> float:
    """Median positive step between sorted stamps, in the file's numbers (for :func:`infer_time_unit`)."""
    d = np.diff(np.sort(raw[np.isfinite(raw)]))
    d = d[d > 0]
    return float(np.median(d)) if d.size else 0.0


def _exact_integer_column(table: Table, idx: int) -> np.ndarray | None:
    """Column ``idx`` of a text table re-read as int64 (None when it is not all integers)."""
    if table.line_of_row is None or Path(table.path).suffix in (".npy", ".npz"):
        return None
    text = read_text(Path(table.path), "data file").splitlines()
    delim = table.delimiter
    try:
        return np.array(
            [int((text[k - 1].split(delim) if delim else text[k - 1].split())[idx]) for k in table.line_of_row],
            dtype=np.int64,
        )
    except (ValueError, IndexError, OverflowError):
        return None


def read_columns(
    path: str | Path,
    columns: str | Sequence[str | int] | Mapping[str, str | int] | None = None,
    *,
    units: str | Mapping[str, str] | None = None,
    time_column: str | int | None = None,
    time_unit: str | None = None,
    freq: float | None = None,
    gap_factor: float = GAP_FACTOR,
) -> Columns:
    """Several columns of a CSV/TXT/NPY file in SI, with an optional time column
    (docs/guide/theory.rst, 'Conventions' and 'Interfaces').

    ``columns``: a mapping output name -> file column (name or 0-based index), a list of file columns
    (output names = column names), or None for every column except the time column. ``units``: see
    :func:`unit_for`; increments (``rad``, ``deg``, ``m/s``) stay increments here (converted to SI).
    ``time_column`` in ``time_unit`` (s, ms, us/µs, ns): the rows are sorted, duplicates dropped and the
    rate inferred and checked against ``freq`` (:func:`clean_time`). Without ``time_column`` a column named
    like a time stamp (``t``, ``time``, ``stamp``, ...) is the time; without ``time_unit`` the unit comes
    from the column's name or the stamp spacing (:mod:`imunoise.io.time_column`, which also refuses a
    given unit that makes no IMU rate when another one does).
    """
    if time_unit is not None and time_unit not in TIME_UNITS:
        raise UnitError(f"unknown time unit {time_unit!r}; use one of {', '.join(TIME_UNITS)}")
    table = read_table(path)
    cmap = parse_column_map(columns)
    t_idx, t_found = time_index(table, time_column, cmap)
    units_from_file = False
    if table.units:
        if units is None:
            units, units_from_file = dict(table.units), True  # the file says (e.g. the ADIS .npz 'units')
        else:
            _check_given_units(table, units)
    pairs = column_pairs(table, cmap, t_idx)
    data = table.data
    t = None
    report = None
    extra: dict[str, Any] = {}
    if t_idx is not None:
        name = table.columns[t_idx]
        t_raw = data[:, t_idx]
        source = f"{path} time column {name!r}"
        exact = _exact_integer_column(table, t_idx) if np.nanmax(np.abs(t_raw)) > 2.0**53 else None
        step = stamp_step(t_raw if exact is None else (exact - exact[0]).astype(float))
        time_unit, note = infer_time_unit(step, stated_time_unit(time_unit, name, t_found), source)
        if note:
            warnings.warn(note, TimingWarning, stacklevel=2)
        if exact is not None:
            # epoch stamps in ns/µs exceed float64's 2^53 integer range: take differences in integers
            t_rel = time_to_seconds((exact - exact[0]).astype(float), time_unit)
            t = t_rel + time_to_seconds(np.array([float(exact[0])]), time_unit)[0]
        else:
            t = time_to_seconds(t_raw, time_unit)
            t_rel = t - t[0] if t.size and np.isfinite(t[0]) else t
        found = ", found by its name" if t_found else ""
        keep, report = clean_time(t_rel, source=f"{source} ({time_unit}{found})", freq=freq, gap_factor=gap_factor)
        if keep.size != t.size or np.any(keep[1:] < keep[:-1]):
            data = data[keep]
        t = t[keep]
        extra = {"time_column": name, "time_unit": time_unit, "time_column_found": t_found}
    values: dict[str, np.ndarray] = {}
    unit: dict[str, str] = {}
    source_unit: dict[str, str] = {}
    colname: dict[str, str] = {}
    for name, idx in pairs:
        v = np.ascontiguousarray(data[:, idx], dtype=float)
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            raise DataError(
                f"{path}: column {table.columns[idx]!r} has {bad.size} non-finite value(s) (NaN/Inf); "
                "remove or interpolate them"
            )
        u = unit_for(name, table.columns[idx], units)
        if u:
            quantity_of(u)  # raises UnitError naming the known units
            v = to_si(v, u)
        values[name] = v
        unit[name] = si_unit(u) if u else "u"
        source_unit[name] = u or "u"
        colname[name] = table.columns[idx]
    return Columns(
        path=str(path),
        names=[n for n, _ in pairs],
        values=values,
        unit=unit,
        source_unit=source_unit,
        column=colname,
        t=t,
        report=report,
        extra={"freq_hz": table.freq_hz, "units_from_file": units_from_file, **extra},
    )


def _check_given_units(table: Table, units: str | Mapping[str, str]) -> None:
    """Warn when a unit given on the command line contradicts the unit the file states for a column."""
    for col, file_unit in table.units.items():
        given = unit_for(col, col, units)
        if given and file_unit and given != file_unit:
            warnings.warn(
                f"{table.path}: column {col!r} is in {file_unit} according to the file, but --units says {given}; "
                "using --units",
                UnitWarning,
                stacklevel=3,
            )
