"""Generic tabular readers: CSV/TXT (with or without a header) and NumPy ``.npy``/``.npz`` (SPEC §12).

The reader picks the delimiter (comma, semicolon, tab or white space), skips ``#`` comments, finds a
header line if there is one, and returns float columns. Bad cells, NaN and Inf are reported with the
file line they are on, so the user can find them.

:func:`read_columns` maps several columns (by name or 0-based index) to output names with a unit per
column (SPEC §1: converted to SI at the boundary) and an optional time column in s/ms/µs/ns;
:func:`clean_time` sorts the stamps, drops and counts duplicates, reports gaps and the sampling jitter and
infers (or checks) the sample rate. The same report is used by the ROS bag reader.
"""

from __future__ import annotations

import io
import warnings
import zipfile
import zlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.errors import DataError, UnitError
from imunoise.io.files import is_number, read_text
from imunoise.io.text_layout import text_layout
from imunoise.io.time_column import find_time_column, infer_time_unit, stated_time_unit
from imunoise.units import TIME_UNITS, quantity_of, si_unit, time_to_seconds, to_si

__all__ = [
    "Table",
    "read_table",
    "read_series",
    "Series",
    "TimeReport",
    "TimingWarning",
    "CutLineWarning",
    "parse_rows",
    "UnitWarning",
    "clean_time",
    "Columns",
    "read_columns",
    "unit_for",
    "parse_column_map",
    "column_pairs",
    "time_index",
    "stamp_step",
    "GAP_FACTOR",
    "RATE_TOLERANCE",
]

GAP_FACTOR = 5.0
"""A step longer than this many median steps is a gap (same rule as the KF-GINS reader)."""

RATE_TOLERANCE = 0.01
"""Relative difference allowed between a given --freq and the rate of the time stamps."""


@dataclass(frozen=True)
class Table:
    """Float columns of a file; ``first_line`` is the 1-based file line of data row 0."""

    columns: list[str]
    data: np.ndarray  # (n, k)
    path: str
    first_line: int
    line_of_row: np.ndarray | None = None  # file line of each row (when comments/blank lines are skipped)
    delimiter: str | None = None  # text files: the column separator (None = white space)
    units: dict[str, str] = field(default_factory=dict)  # unit per column when the file says (.npz 'units')
    freq_hz: float | None = None  # sample rate when the file says (.npz 'freq_hz')

    def column_index(self, column: str | int | None) -> int:
        k = self.data.shape[1]
        if column is None:
            if k == 1:
                return 0
            raise DataError(
                f"{self.path} has {k} columns ({', '.join(self.columns)}); choose one with --column NAME|INDEX"
            )
        if isinstance(column, str) and not column.lstrip("-").isdigit():
            if column in self.columns:
                return self.columns.index(column)
            raise DataError(f"no column {column!r} in {self.path}; columns are: {', '.join(self.columns)}")
        idx = int(column)
        if not -k <= idx < k:
            raise DataError(f"column index {idx} is out of range: {self.path} has {k} columns (0..{k - 1})")
        return idx % k

    def line(self, row: int) -> int:
        return int(self.line_of_row[row]) if self.line_of_row is not None else self.first_line + row


@dataclass(frozen=True)
class Series:
    """One column in SI units."""

    values: np.ndarray
    unit: str  # SI unit of ``values``
    name: str
    source_unit: str


_NUMPY_HINT = (
    "it must be a plain numeric array saved with numpy.save/numpy.savez (pickled objects are refused "
    "for safety)"
)


def _read_numpy(path: Path, kind: str) -> Table:
    """A .npy array, or a .npz with ``data`` (+ optional ``columns``, ``units``, ``freq_hz``) or 1-D arrays."""
    with open(path, "rb") as fh:
        magic = fh.read(6)
    if kind == ".npy" and magic != b"\x93NUMPY" and not zipfile.is_zipfile(path):
        raise DataError(f"{path} is not a NumPy .npy file (no NumPy header); {_NUMPY_HINT}")
    if kind == ".npz" and not zipfile.is_zipfile(path) and magic != b"\x93NUMPY":
        raise DataError(f"{path} is not a NumPy .npz archive (not a zip file); {_NUMPY_HINT}")
    try:
        if kind == ".npy":
            arr = np.load(path, allow_pickle=False)
            if not isinstance(arr, np.ndarray):
                raise DataError(f"{path}: not a .npy array file (a .npz archive?); rename it to .npz")
            names = None
            units: dict[str, str] = {}
            freq = None
        else:
            with np.load(path, allow_pickle=False) as z:
                if not hasattr(z, "files"):
                    raise DataError(f"{path}: not a .npz archive (a single .npy array?); rename it to .npy")
                if "data" in z:
                    arr = z["data"]
                    names = [str(c) for c in z["columns"]] if "columns" in z else None
                else:
                    keys = [k for k in z.files if z[k].ndim == 1 and z[k].size > 1 and z[k].dtype.kind in "iuf"]
                    if not keys:
                        raise DataError(f"{path}: no 1-D arrays or 'data' array found (keys: {z.files})")
                    arr = np.column_stack([z[k] for k in keys])
                    names = keys
                raw_units = z["units"] if "units" in z else None
                freq = float(z["freq_hz"]) if "freq_hz" in z and z["freq_hz"].size == 1 else None
                units = {}
                arr = arr.reshape(-1, 1) if arr.ndim == 1 else arr
                if raw_units is not None and arr.ndim == 2:
                    cols = names or [str(i) for i in range(arr.shape[1])]
                    u = np.atleast_1d(raw_units).astype(str)
                    if u.size == 1:
                        units = {c: str(u[0]) for c in cols}
                    elif u.size == len(cols):
                        units = {c: str(x) for c, x in zip(cols, u)}
                    else:
                        raise DataError(
                            f"{path}: 'units' holds {u.size} entries for {len(cols)} columns; give one per column"
                        )
        arr = np.asarray(arr)
        arr = arr.reshape(-1, 1) if arr.ndim == 1 else arr
        if arr.ndim != 2:
            raise DataError(f"{path}: expected a 1-D or 2-D array, got shape {arr.shape}")
        if arr.dtype.kind not in "iufb":
            raise DataError(f"{path}: the array holds {arr.dtype} values, not numbers")
        data = arr.astype(float)
    except DataError:
        raise
    except EOFError as exc:
        raise DataError(f"{path}: the file ends early (truncated?); {_NUMPY_HINT}") from exc
    except (ValueError, OSError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
        reason = "it holds pickled Python objects" if "pickle" in str(exc) else str(exc)
        raise DataError(f"{path}: not a readable NumPy {kind} file ({reason}); {_NUMPY_HINT}") from exc
    names = names or [str(i) for i in range(data.shape[1])]
    if len(names) != data.shape[1]:
        raise DataError(f"{path}: 'columns' names {len(names)} columns but 'data' has {data.shape[1]}")
    if freq is not None and not (np.isfinite(freq) and freq > 0):
        raise DataError(f"{path}: 'freq_hz' must be a positive rate in Hz, got {freq}")
    return Table(names, data, str(path), 1, units=units, freq_hz=freq)


def parse_rows(path: str | Path, rows: Sequence[tuple[int, str]], delim: str | None, n_fields: int) -> np.ndarray:
    """The numbers of text ``rows`` ((line number, line) pairs; ``delim`` None = any white space) as an
    (n, ``n_fields``) float array; a bad line raises one DataError naming it (field count or the token)."""
    try:
        return np.loadtxt(io.StringIO("\n".join(ln for _, ln in rows)), delimiter=delim, ndmin=2, dtype=float)
    except ValueError as exc:
        for lineno, ln in rows:
            toks = [t.strip() for t in (ln.split(delim) if delim else ln.split())]
            if len(toks) != n_fields:
                raise DataError(f"{path}, line {lineno}: {len(toks)} fields, expected {n_fields}") from exc
            bad = [t for t in toks if not is_number(t)]
            if bad:
                raise DataError(f"{path}, line {lineno}: cannot read {bad[0]!r} as a number") from exc
        raise DataError(f"{path}: {exc}") from exc


def _drop_cut_lines(path: Path, rows: list[tuple[int, str]], split: Callable[[str], list[str]],
                    n_header: int | None) -> list[tuple[int, str]]:
    """``rows`` without a cut first or last data line, with a warning each.

    A logger stopped (or started) mid-write leaves a first or last line with fewer fields than the rest; such a
    line is dropped when every other line of the first (last) ten has the usual count: the header's, or the
    most common one. Any other ragged line is an error of the reader, as before."""
    if len(rows) < 3:
        return rows
    head = [len(split(ln)) for _, ln in rows[:11]]
    usual = n_header or max(set(head), key=head.count)
    out = rows
    if head[0] < usual and all(c == usual for c in head[1:]):
        warnings.warn(f"{path}, line {rows[0][0]}: {head[0]} fields where the others have {usual} (a cut line); "
                      "skipped", CutLineWarning, stacklevel=3)
        out = out[1:]
    tail = [len(split(ln)) for _, ln in out[-11:]]
    if len(out) > 2 and tail[-1] < usual and all(c == usual for c in tail[:-1]):
        warnings.warn(f"{path}, line {out[-1][0]}: {tail[-1]} fields where the others have {usual} (a cut line); "
                      "skipped", CutLineWarning, stacklevel=3)
        out = out[:-1]
    return out


def read_table(path: str | Path) -> Table:
    """Read a CSV/TXT (optionally .gz) or .npy/.npz file into float columns."""
    path = Path(path)
    if not path.exists():
        raise DataError(f"file not found: {path}")
    suffixes = path.suffixes
    if suffixes and suffixes[-1] in (".npy", ".npz"):
        return _read_numpy(path, suffixes[-1])

    text = read_text(path, "data file")  # binary junk, truncated .gz: one DataError naming the file
    raw_lines = text.splitlines()
    content = [(i + 1, ln) for i, ln in enumerate(raw_lines) if ln.strip() and not ln.lstrip().startswith("#")]
    layout = text_layout(path, content)  # separator, decimal comma, header (refused when it misnames the rows)
    rows = content[1:] if layout.has_header else content
    if not rows:
        raise DataError(f"{path} has a header but no data rows")
    if layout.decimal_comma:
        rows = [(k, layout.normalise(ln)) for k, ln in rows]
    rows = _drop_cut_lines(path, rows, layout.split, len(layout.names) if layout.has_header else None)
    columns = layout.names if layout.has_header else [str(i) for i in range(len(layout.split(rows[0][1])))]
    data = parse_rows(path, rows, layout.delimiter, len(columns))
    if data.shape[1] != len(columns):
        raise DataError(f"{path}: the rows have {data.shape[1]} fields but the first data line has {len(columns)}")
    line_of_row = np.array([lineno for lineno, _ in rows])
    return Table(columns, data, str(path), int(line_of_row[0]), line_of_row, layout.delimiter)


def read_series(
    path: str | Path,
    *,
    column: str | int | None = None,
    units: str | None = None,
) -> Series:
    """One column of a file, checked (finite, enough samples) and converted to SI.

    ``units`` is the unit the file is in (``rad/s``, ``deg/s``, ``deg/h``, ``m/s2``, ``g``, ``mg``, ...);
    when omitted the values are taken as already SI and the unit is reported as ``"u"`` (unknown).
    """
    table = read_table(path)
    idx = table.column_index(column)
    units = units or table.units.get(table.columns[idx])  # the file's own unit when it states one
    values = np.ascontiguousarray(table.data[:, idx], dtype=float)
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        row = int(bad[0])
        raise DataError(
            f"{path}: column {table.columns[idx]!r} has {bad.size} non-finite value(s) (NaN/Inf); "
            f"first at data row {row} (file line {table.line(row)}). Remove or interpolate them."
        )
    if units:
        values = to_si(values, units)
        unit = si_unit(units)
    else:
        unit = "u"
    return Series(values, unit, table.columns[idx], units or "u")


# ----------------------------------------------------------------------------------------------
# time stamps: sort, duplicates, gaps, rate and jitter
# ----------------------------------------------------------------------------------------------
class CutLineWarning(UserWarning):
    """A cut first or last line of a table (a logger started or stopped mid-write) was skipped."""


class UnitWarning(UserWarning):
    """The units of the data are doubtful: no unit given and the values cannot be SI, or the file and
    the command line disagree."""


class TimingWarning(UserWarning):
    """A time-stamp problem that was handled: unsorted stamps sorted, duplicates dropped, gaps found."""


@dataclass(frozen=True)
class TimeReport:
    """What :func:`clean_time` found and did. Times in s; ``jitter_s`` is the robust standard deviation
    (1.4826·MAD) of the steps outside gaps; ``rate_hz`` = 1 / mean step outside gaps."""

    source: str
    n_in: int
    n_kept: int
    n_unsorted: int
    n_duplicates: int
    n_gaps: int
    largest_gap_s: float
    median_dt_s: float
    jitter_s: float
    rate_hz: float

    @property
    def jitter_rel(self) -> float:
        return self.jitter_s / self.median_dt_s if self.median_dt_s > 0 else float("nan")

    def summary(self) -> str:
        parts = [
            f"{self.n_kept} samples from {self.source}",
            f"rate {self.rate_hz:.6g} Hz (median step {1e3 * self.median_dt_s:.6g} ms, "
            f"jitter {1e6 * self.jitter_s:.3g} µs = {100 * self.jitter_rel:.3g} % of a step)",
        ]
        if self.n_unsorted:
            parts.append(f"{self.n_unsorted} out-of-order stamps sorted")
        if self.n_duplicates:
            parts.append(f"{self.n_duplicates} duplicated stamps dropped")
        if self.n_gaps:
            parts.append(f"{self.n_gaps} gaps > {GAP_FACTOR:g} steps (largest {self.largest_gap_s:.6g} s)")
        return "; ".join(parts)

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def clean_time(
    t: np.ndarray,
    *,
    source: str = "time stamps",
    freq: float | None = None,
    gap_factor: float = GAP_FACTOR,
    tolerance: float = RATE_TOLERANCE,
) -> tuple[np.ndarray, TimeReport]:
    """Indices that put ``t`` in time order without duplicates, and a :class:`TimeReport`.

    Out-of-order stamps are sorted (stable), duplicates dropped (the first kept), both counted and warned
    about with :class:`TimingWarning`; gaps longer than ``gap_factor`` median steps are counted and warned.
    The rate is 1/(mean step outside gaps). With ``freq`` given, a rate that differs by more than ``tolerance``
    (relative) raises :class:`DataError`: the noise densities scale with √f, so a wrong rate is a wrong
    model.
    """
    t = np.asarray(t, dtype=float)
    if t.ndim != 1:
        raise DataError(f"{source}: time must be 1-D, got shape {t.shape}")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise DataError(f"{source}: {bad.size} non-finite time stamp(s), first at sample {bad[0]}; remove them")
    if t.size < 2:
        raise DataError(f"{source}: need at least 2 time stamps, got {t.size}")
    n_unsorted = int(np.count_nonzero(np.diff(t) < 0))
    order = np.argsort(t, kind="stable") if n_unsorted else np.arange(t.size)
    ts = t[order]
    d = np.diff(ts)
    dup = np.flatnonzero(d == 0) + 1
    keep = np.ones(t.size, dtype=bool)
    keep[dup] = False
    idx = order[keep]
    ts = ts[keep]
    if ts.size < 2:
        raise DataError(f"{source}: all {t.size} time stamps are equal")
    d = np.diff(ts)
    med = float(np.median(d))
    gaps = d[d > gap_factor * med]
    regular = d[d <= gap_factor * med]
    jitter = float(1.4826 * np.median(np.abs(regular - np.median(regular)))) if regular.size else 0.0
    # the mean of the regular steps (not the median): stamps quantised by float64 or a clock tick still
    # average to the true step. 9 significant digits: integer-ns stamps converted to float carry ~1e-13
    # relative noise that would otherwise show up as "200.0000000001819 Hz" in every file downstream
    rate = float(f"{1.0 / float(np.mean(regular)) if regular.size else 1.0 / med:.9g}")
    report = TimeReport(
        source=source,
        n_in=int(t.size),
        n_kept=int(ts.size),
        n_unsorted=n_unsorted,
        n_duplicates=int(dup.size),
        n_gaps=int(gaps.size),
        largest_gap_s=float(gaps.max()) if gaps.size else 0.0,
        median_dt_s=med,
        jitter_s=jitter,
        rate_hz=rate,
    )
    if n_unsorted:
        warnings.warn(f"{source}: {n_unsorted} out-of-order time stamps; sorted", TimingWarning, stacklevel=2)
    if dup.size:
        warnings.warn(
            f"{source}: dropped {dup.size} samples with a duplicated time stamp (the first of each kept)",
            TimingWarning,
            stacklevel=2,
        )
    if gaps.size:
        warnings.warn(
            f"{source}: {gaps.size} gaps longer than {gap_factor:g} sample steps (largest {gaps.max():.6g} s); "
            "the wavelet variance treats the samples as contiguous, so model static segments separately "
            "if the gaps are long",
            TimingWarning,
            stacklevel=2,
        )
    if freq is not None:
        if not freq > 0:
            raise DataError(f"--freq must be a positive rate in Hz, got {freq}")
        if abs(rate - freq) > tolerance * freq:
            raise DataError(
                f"{source}: the time stamps give {rate:.6g} Hz (median step {med:.6g} s) but --freq is {freq:g} Hz; "
                "fix --freq (or --time-unit) — the noise densities scale with the rate"
            )
    return idx, report


# ----------------------------------------------------------------------------------------------
# several columns with units
# ----------------------------------------------------------------------------------------------
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
    """Several columns of a CSV/TXT/NPY file in SI, with an optional time column (SPEC §1, §12).

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
