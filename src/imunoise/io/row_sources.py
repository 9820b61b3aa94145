"""Rows of a table file read a piece at a time, before any column mapping (docs/guide/theory.rst, 'Interfaces'):
``.npy`` through a
memory map, ``.npz`` member by member, CSV/TXT (optionally .gz) a few ten thousand lines at a time. Each
reader returns the file's :class:`RowsHead` (column names, units, size) and a generator of row blocks;
:mod:`imunoise.io.imu_stream` maps the columns to SI."""

from __future__ import annotations

import gzip
import zipfile
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.errors import DataError
from imunoise.io.files import looks_binary
from imunoise.io.table import Table, parse_rows
from imunoise.io.text_layout import text_layout

__all__ = ["RowsHead", "npy_rows", "npz_rows", "text_rows"]


@dataclass
class RowsHead:
    """Column names, the file's own units and rate, the row count (estimated for text) and the size."""

    table: Table
    n_rows: int
    size: int
    sample: np.ndarray | None = None  # the first rows (text, .npy): the stamp unit is inferred from them


def _numpy_error(path: Path, kind: str, exc: Exception) -> DataError:
    reason = "it holds pickled Python objects" if "pickle" in str(exc) or "object" in str(exc) else str(exc)
    return DataError(
        f"{path}: not a readable NumPy {kind} file ({reason}); it must be a plain numeric array saved with "
        "numpy.save/numpy.savez (pickled objects are refused for safety)"
    )


def npy_rows(path: Path, chunk_rows: int) -> tuple[RowsHead, Callable[[], Iterator[tuple[np.ndarray, int, Any]]]]:
    with open(path, "rb") as fh:
        magic = fh.read(6)
    if magic != b"\x93NUMPY":
        raise DataError(
            f"{path} is not a NumPy .npy file (no NumPy header); it must be a plain numeric array saved with "
            "numpy.save (pickled objects are refused for safety)"
        )
    try:
        arr = np.load(path, mmap_mode="r", allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise _numpy_error(path, ".npy", exc) from exc
    arr = arr.reshape(-1, 1) if arr.ndim == 1 else arr
    if arr.ndim != 2:
        raise DataError(f"{path}: expected a 1-D or 2-D array, got shape {arr.shape}")
    if arr.dtype.kind not in "iufb":
        raise DataError(f"{path}: the array holds {arr.dtype} values, not numbers")
    n, k = arr.shape
    row_bytes = arr.dtype.itemsize * k
    table = Table([str(i) for i in range(k)], np.empty((0, k)), str(path), 1)

    def rows() -> Iterator[tuple[np.ndarray, int, Any]]:
        for i in range(0, n, chunk_rows):
            block = np.asarray(arr[i : i + chunk_rows], dtype=float)
            yield block, block.shape[0] * row_bytes, None

    return RowsHead(table, n, n * row_bytes, np.asarray(arr[:200], dtype=float)), rows


def npz_rows(path: Path, chunk_rows: int) -> tuple[RowsHead, Callable[[], Iterator[tuple[np.ndarray, int, Any]]]]:
    """A .npz read member by member: ``data`` (+ ``columns``, ``units``, ``freq_hz``) or its 1-D arrays,
    each member decompressed as it is read."""
    if not zipfile.is_zipfile(path):
        raise DataError(
            f"{path} is not a NumPy .npz archive (not a zip file); it must be a plain numeric array saved with "
            "numpy.savez (pickled objects are refused for safety)"
        )
    try:
        with np.load(path, allow_pickle=False) as z:
            files = list(z.files)
            meta = {key: z[key] for key in ("columns", "units", "freq_hz") if key in files}
            with zipfile.ZipFile(path) as zf:
                headers = {key: _member_header(zf, key) for key in files if key not in meta}
    except DataError:
        raise
    except (ValueError, OSError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
        raise _numpy_error(path, ".npz", exc) from exc
    if "data" in headers:
        members = ["data"]
        shape = headers["data"][0]
        k = 1 if len(shape) == 1 else int(np.prod(shape[1:]))
        if len(shape) > 2:
            raise DataError(f"{path}: expected a 1-D or 2-D array, got shape {shape}")
        names = [str(c) for c in meta["columns"]] if "columns" in meta else [str(i) for i in range(k)]
    else:
        members = [
            key for key, (shape, _, dt) in headers.items() if len(shape) == 1 and shape[0] > 1 and dt.kind in "iuf"
        ]
        if not members:
            raise DataError(f"{path}: no 1-D arrays or 'data' array found (keys: {files})")
        lengths = {headers[m][0][0] for m in members}
        if len(lengths) != 1:
            raise DataError(f"{path}: the 1-D arrays have different lengths {sorted(lengths)}")
        k = len(members)
        names = members
    if len(names) != k:
        raise DataError(f"{path}: 'columns' names {len(names)} columns but 'data' has {k}")
    for m in members:
        shape, fortran, dt = headers[m]
        if dt.kind not in "iufb":
            raise DataError(f"{path}: the array holds {dt} values, not numbers")
        if fortran and len(shape) == 2 and shape[1] > 1:
            raise DataError(f"{path}: member {m!r} is stored column-major; save it with numpy.savez (C order)")
    units: dict[str, str] = {}
    if "units" in meta:
        u = np.atleast_1d(meta["units"]).astype(str)
        if u.size == 1:
            units = {c: str(u[0]) for c in names}
        elif u.size == len(names):
            units = {c: str(x) for c, x in zip(names, u)}
        else:
            raise DataError(f"{path}: 'units' holds {u.size} entries for {len(names)} columns; give one per column")
    freq = float(meta["freq_hz"]) if "freq_hz" in meta and meta["freq_hz"].size == 1 else None
    if freq is not None and not (np.isfinite(freq) and freq > 0):
        raise DataError(f"{path}: 'freq_hz' must be a positive rate in Hz, got {freq}")
    n = int(headers[members[0]][0][0])
    table = Table(names, np.empty((0, k)), str(path), 1, units=units, freq_hz=freq)
    size = path.stat().st_size

    def rows() -> Iterator[tuple[np.ndarray, int, Any]]:
        with zipfile.ZipFile(path) as zf:
            fhs = [zf.open(m + ".npy") for m in members]
            try:
                dts = []
                for fh, m in zip(fhs, members):
                    _read_npy_header(fh)
                    dts.append(headers[m][2])
                widths = [1 if len(headers[m][0]) == 1 else headers[m][0][1] for m in members]
                done = 0
                while done < n:
                    r = min(chunk_rows, n - done)
                    cols = []
                    for fh, dt, w in zip(fhs, dts, widths):
                        buf = fh.read(r * w * dt.itemsize)
                        if len(buf) != r * w * dt.itemsize:
                            raise DataError(f"{path}: the file ends early (truncated?)")
                        cols.append(np.frombuffer(buf, dtype=dt).reshape(r, w).astype(float))
                    done += r
                    yield np.hstack(cols), int(size * r / n), None
            except (OSError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
                raise _numpy_error(path, ".npz", exc) from exc
            finally:
                for fh in fhs:
                    fh.close()

    return RowsHead(table, n, size), rows


def _read_npy_header(fh) -> tuple[tuple[int, ...], bool, np.dtype]:
    version = np.lib.format.read_magic(fh)
    if version == (1, 0):
        return np.lib.format.read_array_header_1_0(fh)
    return np.lib.format.read_array_header_2_0(fh)


def _member_header(zf: zipfile.ZipFile, key: str) -> tuple[tuple[int, ...], bool, np.dtype]:
    with zf.open(key + ".npy") as fh:
        shape, fortran, dt = _read_npy_header(fh)
    if dt.hasobject:
        raise DataError(
            f"{zf.filename}: not a readable NumPy .npz file (it holds pickled Python objects); pickled objects "
            "are refused for safety"
        )
    return shape, fortran, dt


def text_rows(path: Path, chunk_rows: int) -> tuple[RowsHead, Callable[[], Iterator[tuple[np.ndarray, int, Any]]]]:
    """A CSV/TXT (optionally .gz) read ``chunk_rows`` lines at a time, with the header and delimiter rules
    of :func:`imunoise.io.tabular.read_table` found on its first lines."""
    gz = path.suffix == ".gz"
    size = path.stat().st_size
    head_lines: list[tuple[int, str]] = []
    head_bytes = 0
    try:
        with _open_text(path, gz) as (fh, raw):
            first = fh.peek(8192)[:8192] if hasattr(fh, "peek") else b""
            if looks_binary(first):
                raise DataError(
                    f"data file {path} is not a text file (binary content near the start); give a CSV/TXT table "
                    "(or .npy/.npz for NumPy arrays)"
                )
            for lineno, b in enumerate(fh, 1):
                line = _decode(b)
                if line.strip() and not line.lstrip().startswith("#"):
                    head_lines.append((lineno, line))
                    if len(head_lines) >= 200:
                        break
            head_bytes = raw.tell()
    except (EOFError, gzip.BadGzipFile, zlib.error) as exc:
        raise DataError(f"data file {path}: not a valid or complete gzip file ({exc}); get the file again") from exc
    if not head_lines:
        raise DataError(f"{path} has no data lines")
    layout = text_layout(path, head_lines)  # separator, decimal comma, header: the rules of read_table
    names = layout.names
    if layout.has_header and len(head_lines) < 2:
        raise DataError(f"{path} has a header but no data rows")
    header_line = head_lines[0][0] if layout.has_header else 0
    per_line = max(head_bytes / max(head_lines[-1][0], 1), 1.0)
    n_est = int(size / per_line)
    table = Table(names, np.empty((0, len(names))), str(path), 1, delimiter=layout.delimiter)

    def parse(rows: list[tuple[int, str]]) -> np.ndarray:
        if layout.decimal_comma:
            rows = [(k, layout.normalise(ln)) for k, ln in rows]
        return parse_rows(path, rows, layout.delimiter, len(names))

    first_rows = head_lines[1:] if layout.has_header else head_lines
    try:
        sample = parse(first_rows[: min(len(first_rows), 200)]) if first_rows else None
    except DataError:
        sample = None  # the bad line is reported when its block is read

    def rows() -> Iterator[tuple[np.ndarray, int, Any]]:
        pos = 0
        try:
            with _open_text(path, gz) as (fh, raw):
                block: list[tuple[int, str]] = []
                for lineno, b in enumerate(fh, 1):
                    line = _decode(b).removeprefix("\ufeff") if lineno == 1 else _decode(b)
                    if lineno == header_line or not line.strip() or line.lstrip().startswith("#"):
                        continue
                    block.append((lineno, line))
                    if len(block) == chunk_rows:
                        now = raw.tell()
                        yield parse(block), now - pos, block
                        pos, block = now, []
                if block:
                    yield parse(block), size - pos, block
        except (EOFError, gzip.BadGzipFile, zlib.error) as exc:
            raise DataError(
                f"data file {path}: the gzip stream ends early or is corrupt ({exc}); get the file again"
            ) from exc

    return RowsHead(table, n_est, size, sample), rows


class _open_text:
    """Binary line iterator over a text file (gunzipped for .gz) and the raw file for byte progress."""

    def __init__(self, path: Path, gz: bool) -> None:
        self.raw = open(path, "rb")  # noqa: SIM115 - closed in __exit__
        self.fh = gzip.GzipFile(fileobj=self.raw) if gz else self.raw

    def __enter__(self):
        return self.fh, self.raw

    def __exit__(self, *exc) -> None:
        if self.fh is not self.raw:
            self.fh.close()
        self.raw.close()


def _decode(b: bytes) -> str:
    try:
        return b.decode("utf-8")
    except UnicodeDecodeError:
        return b.decode("latin-1")  # as read_text: a legacy 8-bit text

