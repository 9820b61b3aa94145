"""IMU files read block by block (SPEC §12).

:func:`open_imu_blocks` takes the arguments of :func:`imunoise.io.imu_input.read_imu_source` and gives the
selected columns as (n, k) blocks in SI, read a piece at a time: CSV/TXT (optionally .gz) a few ten
thousand lines at a time, ``.npy`` through a memory map, ``.npz`` member by member, ROS bags message by
message. The column mapping, units, rate and time-stamp rules are those of the whole-file path. Their
wavelet variance in one pass is :func:`imunoise.wv_log.stream_wavelet_variance` (modelling, a later stage).

Differences forced by one pass. Out-of-order stamps (the whole-file path sorts them) raise
:class:`StreamOrderError`; duplicated stamps are dropped on the fly (the first kept, as the batch does).
When the rate comes from the stamps, increments (``rad``, ``m/s``) are fed unscaled and the WV is scaled
by f² at the end (rate = increment·f is linear).
"""

from __future__ import annotations

import gzip
import warnings
import zipfile
import zlib
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.errors import DataError, UnitError
from imunoise.io.files import looks_binary
from imunoise.io.imu_input import check_axis_names
from imunoise.io.rosbag import imu_topic, is_bag, iter_imu_bag
from imunoise.io.tabular import (
    RATE_TOLERANCE,
    Table,
    TimingWarning,
    UnitWarning,
    column_pairs,
    parse_column_map,
    parse_rows,
    stamp_step,
    time_index,
    unit_for,
)
from imunoise.io.text_layout import text_layout
from imunoise.io.time_column import infer_time_unit, stated_time_unit
from imunoise.units import TIME_UNITS, quantity_of, si_unit, time_to_seconds, to_si

__all__ = [
    "CHUNK_ROWS",
    "ImuBlocks",
    "StreamOrderError",
    "open_imu_blocks",
]

CHUNK_ROWS = 1 << 16
"""Rows per block (65536 rows of 7 columns: 3.7 MB of float64)."""

_INCREMENT = ("angle_increment", "velocity_increment")
_RATE_UNIT = {"angle_increment": "rad/s", "velocity_increment": "m/s²"}


class StreamOrderError(DataError):
    """The samples cannot be streamed in file order (time stamps go back): the whole-file path sorts them."""


@dataclass(eq=False)
class ImuBlocks:
    """Selected axes of an IMU file as a one-shot iterator of blocks.

    ``blocks`` yields ``(values, t_rel, t_abs, advance)``: values (n, k) in SI (increments not yet times
    the rate), the stamps relative to the first [s] and as the whole-file path keeps them [s] (None
    without a time source), and the progress made in ``size_unit`` (bytes or messages).
    """

    source: str
    axes: list[str]
    unit: dict[str, str]
    source_unit: dict[str, str]
    increment: list[bool]
    freq: float | None
    n_estimate: int
    size: int
    size_unit: str
    time_source: str | None
    meta: dict[str, Any]
    blocks: Iterator[tuple[np.ndarray, np.ndarray | None, np.ndarray | None, int]]


# ----------------------------------------------------------------------------------------------
# readers
# ----------------------------------------------------------------------------------------------
def open_imu_blocks(
    path: str | Path,
    *,
    topic: str | None = None,
    columns: str | Sequence[str | int] | Mapping[str, str | int] | None = None,
    units: str | Mapping[str, str] | None = None,
    time_column: str | int | None = None,
    time_unit: str | None = None,
    freq: float | None = None,
    stamps: str = "header",
    chunk_rows: int = CHUNK_ROWS,
) -> ImuBlocks:
    """The axes :func:`~imunoise.io.imu_input.read_imu_source` would return, as blocks (module docstring).

    Headers, column names, units and the rate are checked here, before any block is read; bad cells
    and non-finite values raise :class:`DataError` when their block is reached.
    """
    path = Path(path)
    check_axis_names(columns)
    if is_bag(path):
        return _bag_blocks(path, topic, columns, freq, stamps, chunk_rows)
    if not path.exists():
        raise DataError(f"file not found: {path}")
    if time_unit is not None and time_unit not in TIME_UNITS:
        raise UnitError(f"unknown time unit {time_unit!r}; use one of {', '.join(TIME_UNITS)}")
    suffix = path.suffixes[-1] if path.suffixes else ""
    if suffix == ".npy":
        head, rows = _npy_rows(path, chunk_rows)
    elif suffix == ".npz":
        head, rows = _npz_rows(path, chunk_rows)
    else:
        head, rows = _text_rows(path, chunk_rows)
    return _table_blocks(path, head, rows, columns, units, time_column, time_unit, freq)


@dataclass
class _Head:
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


def _npy_rows(path: Path, chunk_rows: int) -> tuple[_Head, Callable[[], Iterator[tuple[np.ndarray, int, Any]]]]:
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

    return _Head(table, n, n * row_bytes, np.asarray(arr[:200], dtype=float)), rows


def _npz_rows(path: Path, chunk_rows: int) -> tuple[_Head, Callable[[], Iterator[tuple[np.ndarray, int, Any]]]]:
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

    return _Head(table, n, size), rows


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


def _text_rows(path: Path, chunk_rows: int) -> tuple[_Head, Callable[[], Iterator[tuple[np.ndarray, int, Any]]]]:
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

    return _Head(table, n_est, size, sample), rows


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


def _table_blocks(
    path: Path,
    head: _Head,
    rows: Callable[[], Iterator[tuple[np.ndarray, int, Any]]],
    columns: Any,
    units: Any,
    time_column: str | int | None,
    time_unit: str | None,
    freq: float | None,
) -> ImuBlocks:
    """Column mapping, units and rate as in :func:`read_columns` + :func:`read_imu_source`."""
    table = head.table
    cmap = parse_column_map(columns)
    t_idx, t_found = time_index(table, time_column, cmap)
    units_from_file = False
    if table.units:
        if units is None:
            units, units_from_file = dict(table.units), True
        else:
            for col, file_unit in table.units.items():
                given = unit_for(col, col, units)
                if given and file_unit and given != file_unit:
                    warnings.warn(
                        f"{table.path}: column {col!r} is in {file_unit} according to the file, but --units says "
                        f"{given}; using --units",
                        UnitWarning,
                        stacklevel=3,
                    )
    pairs = column_pairs(table, cmap, t_idx)
    idx = [i for _, i in pairs]
    axes = [n for n, _ in pairs]
    if t_idx is not None:
        given_unit = stated_time_unit(time_unit, table.columns[t_idx], t_found)
        step = stamp_step(head.sample[:, t_idx]) if head.sample is not None else 0.0
        time_unit, note = infer_time_unit(step, given_unit, f"{path} time column {table.columns[t_idx]!r}")
        if note:
            warnings.warn(note, TimingWarning, stacklevel=3)
    unit, source_unit, factor, increment = {}, {}, [], []
    for name, i in pairs:
        u = unit_for(name, table.columns[i], units)
        if u:
            quantity_of(u)
        factor.append(float(to_si(1.0, u)) if u else 1.0)
        q = quantity_of(u) if u else None
        increment.append(q in _INCREMENT)
        unit[name] = _RATE_UNIT[q] if q in _INCREMENT else (si_unit(u) if u else "u")
        source_unit[name] = u or "u"
    file_freq = table.freq_hz
    if freq and file_freq and abs(float(freq) - file_freq) > RATE_TOLERANCE * file_freq:
        raise DataError(
            f"{path} states its rate as {file_freq:g} Hz but --freq is {float(freq):g} Hz; drop --freq or fix it "
            "(the noise densities scale with the rate)"
        )
    if t_idx is None and not freq and not file_freq:
        raise DataError(f"{path}: give the sample rate with --freq HZ or a time column with --time-column")
    f = float(freq) if freq else (None if t_idx is not None else float(file_freq))
    if f is not None and not f > 0:
        raise DataError(f"--freq must be a positive rate in Hz, got {f}")
    scale = np.array(factor)
    names = [table.columns[i] for i in idx]
    t_name = table.columns[t_idx] if t_idx is not None else None

    def blocks() -> Iterator[tuple[np.ndarray, np.ndarray | None, np.ndarray | None, int]]:
        t0 = None
        exact0 = None
        for data, adv, lines in rows():
            v = data[:, idx] * scale if np.any(scale != 1.0) else np.array(data[:, idx], dtype=float)
            bad = ~np.isfinite(v)
            if bad.any():
                col = names[int(np.flatnonzero(bad.any(axis=0))[0])]
                raise DataError(f"{path}: column {col!r} has non-finite value(s) (NaN/Inf); remove or interpolate them")
            t_rel = t_abs = None
            if t_idx is not None:
                raw_t = np.asarray(data[:, t_idx])
                exact = None
                if lines is not None and (exact0 is not None or np.nanmax(np.abs(raw_t)) > 2.0**53):
                    exact = _exact_integers(lines, t_idx, table.delimiter)
                if exact is not None and (exact0 is not None or t0 is None):
                    # epoch stamps in ns beyond float64's 2^53: differences in integers (as read_columns)
                    exact0 = exact[0] if exact0 is None else exact0
                    t_rel = time_to_seconds((exact - exact0).astype(float), time_unit)
                    t_abs = t_rel + time_to_seconds(np.array([float(exact0)]), time_unit)[0]
                    t0 = t0 if t0 is not None else 0.0
                else:
                    t_abs = time_to_seconds(raw_t, time_unit)
                    if t0 is None:
                        t0 = t_abs[0] if t_abs.size and np.isfinite(t_abs[0]) else 0.0
                    t_rel = t_abs - t0
            yield np.asarray(v, dtype=float), t_rel, t_abs, adv

    meta: dict[str, Any] = {"format": "table", "columns": dict(zip(axes, names))}
    if units_from_file:
        meta["units_from_file"] = True
    if file_freq and not freq and t_idx is None:
        meta["freq_from_file"] = True
    return ImuBlocks(
        source=str(path),
        axes=axes,
        unit=unit,
        source_unit=source_unit,
        increment=increment,
        freq=f,
        n_estimate=head.n_rows,
        size=head.size,
        size_unit="B",
        time_source=f"{path} time column {t_name!r} ({time_unit}{', found by its name' if t_found else ''})"
        if t_name is not None
        else None,
        meta=meta,
        blocks=blocks(),
    )


def _exact_integers(lines: list[tuple[int, str]], idx: int, delim: str | None) -> np.ndarray | None:
    try:
        return np.array([int((ln.split(delim) if delim else ln.split())[idx]) for _, ln in lines], dtype=np.int64)
    except (ValueError, IndexError, OverflowError):
        return None


def _bag_blocks(
    path: Path, topic: str | None, columns: Any, freq: float | None, stamps: str, chunk_rows: int
) -> ImuBlocks:
    """Six axes (or the named subset) of a bag's IMU topic, message by message in bag order."""
    if stamps not in ("header", "bag"):
        raise DataError(f"stamps must be 'header' or 'bag', got {stamps!r}")
    info = imu_topic(path, topic)
    all_axes = [f"{s}_{a}" for s in ("gyro", "accel") for a in "xyz"]
    if columns is None:
        axes = all_axes
    else:
        axes = [c.strip() for c in columns.split(",")] if isinstance(columns, str) else list(columns)
        bad = [c for c in axes if c not in all_axes]
        if bad:
            raise DataError(f"unknown IMU axis {bad[0]!r} for a bag; use any of: {', '.join(all_axes)}")
    idx = [all_axes.index(a) for a in axes]
    unit = {a: "rad/s" if a.startswith("gyro") else "m/s²" for a in axes}
    meta: dict[str, Any] = {"format": "rosbag", "topic": info.name, "frame": "FLU (ROS)"}
    source = {"text": f"{path}:{info.name} header stamps"}

    def blocks() -> Iterator[tuple[np.ndarray, np.ndarray | None, np.ndarray | None, int]]:
        use_bag = stamps == "bag"
        s0 = None
        seen = 0
        header_nonzero = False
        for b in iter_imu_bag(path, info.name, batch=min(chunk_rows, 1 << 14)):
            meta.setdefault("frame_id", b.frame_id)
            if s0 is None and stamps == "header" and b.stamp_ns[0] == 0:
                warnings.warn(
                    f"{path}:{info.name}: the first header stamp is zero; using the bag receive time instead",
                    TimingWarning,
                    stacklevel=2,
                )
                use_bag = True
            if stamps == "header" and use_bag:
                header_nonzero = header_nonzero or bool(np.any(b.stamp_ns))
                if header_nonzero:
                    raise StreamOrderError(
                        f"{path}:{info.name}: the header stamps are zero at the start and not later; "
                        "cannot stream — run without --stream, or pass --stamps bag"
                    )
            st = b.bag_ns if use_bag else b.stamp_ns
            if use_bag:
                source["text"] = f"{path}:{info.name} bag receive time"
            vals = np.hstack([b.gyro, b.accel])[:, idx]
            bad = ~np.isfinite(np.hstack([b.gyro, b.accel])).all(axis=1)
            if bad.any():
                raise DataError(
                    f"{path}:{info.name}: message(s) with NaN/Inf rates, first at message "
                    f"{seen + int(np.flatnonzero(bad)[0])}; filter the bag"
                )
            s0 = int(st[0]) if s0 is None else s0
            seen += st.size
            yield vals, (st - s0).astype(float) * 1e-9, st.astype(float) * 1e-9, st.size

    it = blocks()
    return ImuBlocks(
        source=f"{path}:{info.name}",
        axes=axes,
        unit=unit,
        source_unit=dict(unit),
        increment=[False] * len(axes),
        freq=float(freq) if freq else None,
        n_estimate=info.count,
        size=info.count,
        size_unit="msg",
        time_source=None,
        meta=meta | {"_time_source": source},
        blocks=it,
    )
