"""Generic table readers: CSV/TXT (with or without a header) and NumPy ``.npy``/``.npz``
(docs/guide/theory.rst, 'Interfaces').

The reader picks the delimiter (comma, semicolon, tab or white space), skips ``#`` comments, finds a
header line if there is one, and returns float columns. Bad cells, NaN and Inf are reported with the
file line they are on, so the user can find them.
"""

from __future__ import annotations

import io
import warnings
import zipfile
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from imunoise.errors import CutLineWarning, DataError
from imunoise.io.files import is_number, read_text
from imunoise.io.text_layout import text_layout
from imunoise.units import si_unit, to_si

__all__ = ["CutLineWarning", "Series", "Table", "parse_rows", "read_series", "read_table"]


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
        if 1 < arr.shape[0] <= 16 and arr.shape[1] >= 100 * arr.shape[0]:  # a few rows of many samples each
            raise DataError(f"{path}: the array has shape {arr.shape}: {arr.shape[0]} rows of {arr.shape[1]} values, "
                            "i.e. the samples run along the rows; one row per sample and one column per axis is "
                            "expected: save it transposed (numpy.save(path, x.T))")
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
