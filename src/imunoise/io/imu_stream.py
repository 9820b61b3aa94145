"""IMU files read block by block (docs/guide/theory.rst, 'Interfaces').

:func:`open_imu_blocks` takes the arguments of :func:`imunoise.io.imu_input.read_imu_source` and gives the
selected columns as (n, k) blocks in SI, read a piece at a time: CSV/TXT (optionally .gz) a few ten
thousand lines at a time, ``.npy`` through a memory map, ``.npz`` member by member, ROS bags message by
message. The column mapping, units, rate and time-stamp rules are those of the whole-file path. Their
wavelet variance in one pass is :func:`imunoise.noise.wv_log.stream_wavelet_variance` (modelling, a later stage).

Differences forced by one pass. Out-of-order stamps (the whole-file path sorts them) raise
:class:`StreamOrderError`; duplicated stamps are dropped on the fly (the first kept, as the batch does).
When the rate comes from the stamps, increments (``rad``, ``m/s``) are fed unscaled and the WV is scaled
by f² at the end (rate = increment·f is linear).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.errors import DataError, UnitError
from imunoise.io.imu_input import check_axis_names
from imunoise.io.imu_source import UNSET, ImuSource
from imunoise.io.rosbag import imu_topic, is_bag, iter_imu_bag
from imunoise.io.row_sources import RowsHead, npy_rows, npz_rows, text_rows
from imunoise.io.tabular import (
    RATE_TOLERANCE,
    TimingWarning,
    UnitWarning,
    column_pairs,
    parse_column_map,
    stamp_step,
    time_index,
    unit_for,
)
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
    path: str | Path | ImuSource,
    *,
    topic: str | None = UNSET,
    columns: str | Sequence[str | int] | Mapping[str, str | int] | None = UNSET,
    units: str | Mapping[str, str] | None = UNSET,
    time_column: str | int | None = UNSET,
    time_unit: str | None = UNSET,
    freq: float | None = UNSET,
    stamps: str = UNSET,
    chunk_rows: int = CHUNK_ROWS,
) -> ImuBlocks:
    """The axes :func:`~imunoise.io.imu_input.read_imu_source` would return, as blocks (module docstring);
    ``path`` and the reader keywords as there (an :class:`~imunoise.io.imu_source.ImuSource`, or a path).

    Headers, column names, units and the rate are checked here, before any block is read; bad cells
    and non-finite values raise :class:`DataError` when their block is reached.
    """
    src = ImuSource.of(path, topic=topic, columns=columns, units=units, time_column=time_column,
                       time_unit=time_unit, freq=freq, stamps=stamps)
    path, columns, time_unit, freq = Path(src.path), src.columns, src.time_unit, src.freq
    check_axis_names(columns)
    if is_bag(path):
        return _bag_blocks(path, src.topic, columns, freq, src.stamps, chunk_rows)
    if not path.exists():
        raise DataError(f"file not found: {path}")
    if time_unit is not None and time_unit not in TIME_UNITS:
        raise UnitError(f"unknown time unit {time_unit!r}; use one of {', '.join(TIME_UNITS)}")
    suffix = path.suffixes[-1] if path.suffixes else ""
    if suffix == ".npy":
        head, rows = npy_rows(path, chunk_rows)
    elif suffix == ".npz":
        head, rows = npz_rows(path, chunk_rows)
    else:
        head, rows = text_rows(path, chunk_rows)
    return _table_blocks(path, head, rows, columns, src.units, src.time_column, time_unit, freq)



def _table_blocks(
    path: Path,
    head: RowsHead,
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
