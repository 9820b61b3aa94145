"""One entry point from any supported IMU source to SI rate arrays (SPEC §1, §12).

:func:`read_imu_source` reads a ROS bag (``.bag``, ``.db3``, ``.mcap``, ROS 2 folder) or a table
(CSV/TXT/NPY/NPZ) and returns :class:`ImuSeries`: one SI array per axis (rad/s or m/s²), the sample
rate (given, or inferred from the stamps and checked), and the timing report.

Increments in a table (units ``rad``, ``deg``, ``m/s``) become rates with the *nominal* step:
rate = increment·f. Dividing by each sample's own Δt_k would add the time-stamp jitter to the noise.

Decimation (:func:`decimate`): block averaging of k samples keeps the white-noise density
N = σ·√Δt (σ²/k per sample at Δt·k); keeping every k-th sample does not — σ stays the same while Δt grows
k times, so N comes out √k too large. Dropping is therefore refused for noise modelling.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.errors import DataError
from imunoise.io.rosbag import is_bag, read_imu_bag
from imunoise.io.tabular import TimeReport, TimingWarning, clean_time, read_columns
from imunoise.units import quantity_of

__all__ = ["AXES", "ImuSeries", "read_imu_source", "decimate", "sensor_of"]

AXES = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")

_RATE_OF_INCREMENT = {"angle_increment": "rad/s", "velocity_increment": "m/s²"}


def sensor_of(axis: str, unit: str | None = None) -> str | None:
    """``"gyro"`` or ``"accel"`` from an axis name (gyro*/accel*/acc*) or else from its SI unit."""
    low = axis.lower()
    if low.startswith(("gyro", "gyr", "omega", "w_", "angular_velocity")) or low in (
        "gx",
        "gy",
        "gz",
        "wx",
        "wy",
        "wz",
    ):
        return "gyro"
    if low.startswith(("acc", "f_", "linear_acceleration")) or low in ("ax", "ay", "az", "fx", "fy", "fz"):
        return "accel"
    if unit == "rad/s":
        return "gyro"
    if unit == "m/s²":
        return "accel"
    return None


@dataclass(eq=False)
class ImuSeries:
    """Static IMU data per axis in SI: ``data[axis]`` (rad/s or m/s²; ``"u"`` when no unit was given),
    ``freq`` in Hz, ``t`` in s (None for a table without a time column)."""

    source: str
    data: dict[str, np.ndarray]
    unit: dict[str, str]
    source_unit: dict[str, str]
    freq: float
    t: np.ndarray | None = None
    report: TimeReport | None = None
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def axes(self) -> list[str]:
        return list(self.data)

    def __len__(self) -> int:
        return int(next(iter(self.data.values())).size) if self.data else 0

    def describe(self) -> str:
        lines = [f"{self.source}: {len(self)} samples at {self.freq:g} Hz, axes {', '.join(self.axes)}"]
        if self.report is not None:
            lines.append("  " + self.report.summary())
        if self.meta.get("decimated"):
            d = self.meta["decimated"]
            lines.append(f"  block-averaged by {d['k']} (from {d['freq_in']:g} Hz)")
        return "\n".join(lines)


def decimate(x: np.ndarray, k: int, method: str = "average") -> np.ndarray:
    """Block mean of ``k`` samples (a trailing partial block is dropped). ``method="drop"`` (keep every
    k-th sample) raises :class:`DataError`: it keeps σ per sample while the step grows k times, so the
    white-noise density N = σ·√Δt comes out √k too large (module docstring)."""
    if int(k) != k or k < 1:
        raise DataError(f"decimation factor must be a positive whole number, got {k}")
    k = int(k)
    if method == "drop":
        raise DataError(
            f"decimation by dropping samples is refused for noise modelling: keeping every {k}th sample "
            f"keeps the per-sample σ while Δt grows {k}×, so the noise density N = σ·√Δt would come out "
            f"√{k} = {math.sqrt(k):.3g}× too large. Use averaging (--decimate {k} --decimate-method average), "
            "which keeps N"
        )
    if method != "average":
        raise DataError(f"decimation method must be 'average' or 'drop', got {method!r}")
    x = np.asarray(x, dtype=float)
    if k == 1:
        return x
    m = x.shape[0] // k
    if m < 2:
        raise DataError(f"only {x.shape[0]} samples: cannot decimate by {k}")
    return x[: m * k].reshape(m, k, *x.shape[1:]).mean(axis=1)


def _as_rates(values: np.ndarray, source_unit: str, si: str, freq: float) -> tuple[np.ndarray, str]:
    if source_unit == "u":
        return values, si
    q = quantity_of(source_unit)
    if q in _RATE_OF_INCREMENT:
        return values * freq, _RATE_OF_INCREMENT[q]
    return values, si


def read_imu_source(
    path: str | Path,
    *,
    topic: str | None = None,
    columns: str | Sequence[str | int] | Mapping[str, str | int] | None = None,
    units: str | Mapping[str, str] | None = None,
    time_column: str | int | None = None,
    time_unit: str = "s",
    freq: float | None = None,
    decimate_by: int = 1,
    decimate_method: str = "average",
    stamps: str = "header",
) -> ImuSeries:
    """Read IMU data from a ROS bag or a table into SI per-axis arrays.

    Bags: all six axes of ``topic`` (``gyro_x`` … ``accel_z``) unless ``columns`` names a subset; the
    rate comes from the header stamps (checked against ``freq`` when given). Tables: ``columns`` as in
    :func:`imunoise.io.tabular.read_columns`, ``units`` per column, the rate from ``time_column`` or
    ``freq`` (one is needed). ``decimate_by`` > 1 block-averages (:func:`decimate`).
    """
    path = Path(path)
    if is_bag(path):
        bag = read_imu_bag(path, topic, stamps=stamps, freq=freq)
        all_axes = bag.axes()
        wanted = _bag_axes(columns, all_axes)
        data = {a: all_axes[a] for a in wanted}
        unit = {a: "rad/s" if a.startswith("gyro") else "m/s²" for a in wanted}
        series = ImuSeries(
            source=f"{path}:{bag.topic}",
            data=data,
            unit=unit,
            source_unit=dict(unit),
            freq=float(freq) if freq else bag.report.rate_hz,
            t=bag.t,
            report=bag.report,
            meta={"format": "rosbag", "topic": bag.topic, "frame_id": bag.frame_id, "frame": "FLU (ROS)"},
        )
    else:
        cols = read_columns(path, columns, units=units, time_column=time_column, time_unit=time_unit, freq=freq)
        if cols.report is not None:
            f = float(freq) if freq else cols.report.rate_hz
        elif freq:
            f = float(freq)
        else:
            raise DataError(f"{path}: give the sample rate with --freq HZ or a time column with --time-column")
        if not f > 0:
            raise DataError(f"--freq must be a positive rate in Hz, got {f}")
        data, unit = {}, {}
        for name in cols.names:
            data[name], unit[name] = _as_rates(cols.values[name], cols.source_unit[name], cols.unit[name], f)
        series = ImuSeries(
            source=str(path),
            data=data,
            unit=unit,
            source_unit=dict(cols.source_unit),
            freq=f,
            t=cols.t,
            report=cols.report,
            meta={"format": "table", "columns": dict(cols.column)},
        )
    if series.report is not None and not 1.0 <= series.report.rate_hz <= 1e5:
        warnings.warn(
            f"{series.source}: the time stamps give {series.report.rate_hz:.6g} Hz, unusual for an IMU; "
            "check --time-unit",
            TimingWarning,
            stacklevel=2,
        )
    if decimate_by != 1 or decimate_method != "average":
        series = _decimated(series, decimate_by, decimate_method)
    return series


def _bag_axes(columns: Any, all_axes: Mapping[str, np.ndarray]) -> list[str]:
    if columns is None:
        return list(all_axes)
    items = [c.strip() for c in columns.split(",")] if isinstance(columns, str) else list(columns)
    bad = [c for c in items if c not in all_axes]
    if bad:
        raise DataError(f"unknown IMU axis {bad[0]!r} for a bag; use any of: {', '.join(all_axes)}")
    return items


def _decimated(series: ImuSeries, k: int, method: str) -> ImuSeries:
    data = {a: decimate(v, k, method) for a, v in series.data.items()}
    t = decimate(series.t, k, method) if series.t is not None else None
    report = series.report
    if t is not None:
        _, report = clean_time(t - t[0], source=f"{series.source} (block-averaged by {k})")
    meta = dict(series.meta, decimated={"k": int(k), "method": method, "freq_in": series.freq})
    return ImuSeries(
        source=series.source,
        data=data,
        unit=dict(series.unit),
        source_unit=dict(series.source_unit),
        freq=series.freq / k,
        t=t,
        report=report,
        meta=meta,
    )
