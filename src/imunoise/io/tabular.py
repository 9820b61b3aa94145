"""Generic tabular readers: CSV/TXT (with or without a header) and NumPy ``.npy``/``.npz`` (SPEC §12).

The reader picks the delimiter (comma, semicolon, tab or white space), skips ``#`` comments, finds a
header line if there is one, and returns float columns. Bad cells, NaN and Inf are reported with the
file line they are on, so the user can find them.
"""

from __future__ import annotations

import csv
import gzip
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from imunoise.errors import DataError
from imunoise.units import si_unit, to_si

__all__ = ["Table", "read_table", "read_series", "Series"]


@dataclass(frozen=True)
class Table:
    """Float columns of a file; ``first_line`` is the 1-based file line of data row 0."""

    columns: list[str]
    data: np.ndarray  # (n, k)
    path: str
    first_line: int
    line_of_row: np.ndarray | None = None  # file line of each row (when comments/blank lines are skipped)

    def column_index(self, column: str | int | None) -> int:
        k = self.data.shape[1]
        if column is None:
            if k == 1:
                return 0
            raise DataError(
                f"{self.path} has {k} columns ({', '.join(self.columns)}); "
                "choose one with --column NAME|INDEX"
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


def _open_text(path: Path) -> str:
    if path.suffix == ".gz":
        with gzip.open(path, "rt") as fh:
            return fh.read()
    return path.read_text()


def _is_number(tok: str) -> bool:
    try:
        float(tok)
        return True
    except ValueError:
        return False


def read_table(path: str | Path) -> Table:
    """Read a CSV/TXT (optionally .gz) or .npy/.npz file into float columns."""
    path = Path(path)
    if not path.exists():
        raise DataError(f"file not found: {path}")
    suffixes = path.suffixes
    if suffixes and suffixes[-1] == ".npy":
        arr = np.load(path, allow_pickle=False)
        arr = arr.reshape(-1, 1) if arr.ndim == 1 else arr
        if arr.ndim != 2:
            raise DataError(f"{path}: expected a 1-D or 2-D array, got shape {arr.shape}")
        return Table([str(i) for i in range(arr.shape[1])], arr.astype(float), str(path), 1)
    if suffixes and suffixes[-1] == ".npz":
        with np.load(path, allow_pickle=False) as z:
            if "data" in z:
                arr = z["data"]
                names = [str(c) for c in z["columns"]] if "columns" in z else None
            else:
                keys = [k for k in z.files if z[k].ndim == 1 and z[k].size > 1]
                if not keys:
                    raise DataError(f"{path}: no 1-D arrays or 'data' array found (keys: {z.files})")
                arr = np.column_stack([z[k] for k in keys])
                names = keys
        arr = arr.reshape(-1, 1) if arr.ndim == 1 else arr
        names = names or [str(i) for i in range(arr.shape[1])]
        return Table(names, arr.astype(float), str(path), 1)

    text = _open_text(path)
    raw_lines = text.splitlines()
    content = [
        (i + 1, ln) for i, ln in enumerate(raw_lines) if ln.strip() and not ln.lstrip().startswith("#")
    ]
    if not content:
        raise DataError(f"{path} has no data lines")
    sample = "\n".join(ln for _, ln in content[:20])
    try:
        delim = csv.Sniffer().sniff(sample, delimiters=",;\t ").delimiter
    except csv.Error:
        delim = ","
    if delim == " " or ("," not in sample and ";" not in sample and "\t" not in sample):
        delim = None  # any white space

    def split(line: str) -> list[str]:
        return [t.strip() for t in (line.split(delim) if delim else line.split())]

    first = split(content[0][1])
    has_header = not all(_is_number(t) for t in first if t != "")
    columns = first if has_header else [str(i) for i in range(len(first))]
    rows = content[1:] if has_header else content
    if not rows:
        raise DataError(f"{path} has a header but no data rows")
    body = "\n".join(ln for _, ln in rows)
    try:
        data = np.loadtxt(io.StringIO(body), delimiter=delim, ndmin=2, dtype=float)
    except ValueError as exc:
        for lineno, ln in rows:
            toks = split(ln)
            if len(toks) != len(columns):
                raise DataError(
                    f"{path}, line {lineno}: {len(toks)} fields, expected {len(columns)}"
                ) from exc
            bad = [t for t in toks if not _is_number(t)]
            if bad:
                raise DataError(f"{path}, line {lineno}: cannot read {bad[0]!r} as a number") from exc
        raise DataError(f"{path}: {exc}") from exc
    line_of_row = np.array([lineno for lineno, _ in rows])
    return Table(columns, data, str(path), int(line_of_row[0]), line_of_row)


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
