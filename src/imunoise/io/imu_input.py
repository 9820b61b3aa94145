"""One entry point from any supported IMU source to SI rate arrays
(docs/guide/theory.rst, 'Conventions' and 'Interfaces').

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
from imunoise.imu import AXES
from imunoise.io.imu_source import UNSET, ImuSource
from imunoise.io.rosbag import is_bag, read_imu_bag
from imunoise.io.tabular import RATE_TOLERANCE, TimeReport, TimingWarning, UnitWarning, clean_time, read_columns
from imunoise.units import quantity_of

__all__ = [
    "AXES",
    "ImuSeries",
    "read_imu_source",
    "decimate",
    "sensor_of",
    "unknown_unit_messages",
    "degenerate_axis",
    "check_axis_names",
    "DEGENERATE_FRACTION",
]


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
        return describe_series(self.source, len(self), self.freq, self.axes, self.report, self.meta)


def describe_series(source: str, n_samples: int, freq: float, axes: Sequence[str], report: TimeReport | None,
                    meta: Mapping[str, Any], note: str = "") -> str:
    """The lines a fit prints about its input: samples, rate, axes (``note`` appended), the timing report and
    any decimation; shared by the whole-file series and the streamed one."""
    lines = [f"{source}: {n_samples} samples at {freq:g} Hz, axes {', '.join(axes)}{note}"]
    if report is not None:
        lines.append("  " + report.summary())
    if meta.get("decimated"):
        d = meta["decimated"]
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
    path: str | Path | ImuSource,
    *,
    topic: str | None = UNSET,
    columns: str | Sequence[str | int] | Mapping[str, str | int] | None = UNSET,
    units: str | Mapping[str, str] | None = UNSET,
    time_column: str | int | None = UNSET,
    time_unit: str | None = UNSET,
    freq: float | None = UNSET,
    decimate_by: int = 1,
    decimate_method: str = "average",
    stamps: str = UNSET,
) -> ImuSeries:
    """Read IMU data from a ROS bag or a table into SI per-axis arrays.

    ``path`` is an :class:`~imunoise.io.imu_source.ImuSource`, or a path with the reader keywords (those not given
    take the :class:`~imunoise.io.imu_source.ImuSource` defaults; given with an ImuSource they replace its fields).

    Bags: all six axes of ``topic`` (``gyro_x`` … ``accel_z``) unless ``columns`` names a subset; the
    rate comes from the header stamps (checked against ``freq`` when given). Tables: ``columns`` as in
    :func:`imunoise.io.tabular.read_columns`, ``units`` per column, the rate from ``time_column`` or
    ``freq`` (one is needed); a column named like a time stamp is the time column when none is given, and
    the stamp unit is inferred when not given (:mod:`imunoise.io.time_column`). Names given to columns
    (``gyro_x=gx``) must be IMU axes (:data:`AXES`). ``decimate_by`` > 1 block-averages (:func:`decimate`).

    A near-constant axis (:func:`degenerate_axis`) is refused: it has no noise to model.
    """
    src = ImuSource.of(path, topic=topic, columns=columns, units=units, time_column=time_column,
                       time_unit=time_unit, freq=freq, stamps=stamps)
    path, topic, columns, freq = Path(src.path), src.topic, src.columns, src.freq
    check_axis_names(columns)
    if is_bag(path):
        bag = read_imu_bag(path, topic, stamps=src.stamps, freq=freq)
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
        cols = read_columns(path, columns, units=src.units, time_column=src.time_column, time_unit=src.time_unit,
                            freq=freq)
        file_freq = cols.extra.get("freq_hz")
        if freq and file_freq and abs(float(freq) - file_freq) > RATE_TOLERANCE * file_freq:
            raise DataError(
                f"{path} states its rate as {file_freq:g} Hz but --freq is {float(freq):g} Hz; drop --freq or fix it "
                "(the noise densities scale with the rate)"
            )
        if cols.report is not None:
            f = float(freq) if freq else cols.report.rate_hz
        elif freq:
            f = float(freq)
        elif file_freq:
            f = float(file_freq)
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
        if cols.extra.get("time_column") is not None:
            series.meta["time"] = {k: cols.extra[k] for k in ("time_column", "time_unit", "time_column_found")}
        if cols.extra.get("units_from_file"):
            series.meta["units_from_file"] = True
        if file_freq and not freq and cols.report is None:
            series.meta["freq_from_file"] = True
        _check_unknown_units(series)
    if series.report is not None and not 1.0 <= series.report.rate_hz <= 1e5:
        warnings.warn(
            f"{series.source}: the time stamps give {series.report.rate_hz:.6g} Hz, unusual for an IMU; "
            "check --time-unit",
            TimingWarning,
            stacklevel=2,
        )
    for axis, values in series.data.items():
        why = degenerate_axis(values)
        if why:
            col = series.meta.get("columns", {}).get(axis, axis)
            raise DataError(
                f"{series.source}: column {col!r} ({axis}) is {why}: there is no sensor noise to model (a fit "
                "would describe the odd samples only); check the column (--columns) or the recording"
            )
    if decimate_by != 1 or decimate_method != "average":
        series = _decimated(series, decimate_by, decimate_method)
    return series


DEGENERATE_FRACTION = 0.01
"""An axis where fewer than this fraction of the samples (or fewer than 3) differ from the median value is
near-constant (:func:`degenerate_axis`)."""


def degenerate_axis(x: np.ndarray) -> str | None:
    """Why ``x`` cannot be modelled as sensor noise, or None.

    A still IMU's output changes from sample to sample (white noise at least); a series in which all but a
    few samples (fewer than :data:`DEGENERATE_FRACTION` of them, or fewer than 3) hold one value is an
    empty, saturated or unplugged channel, and its wavelet variance comes from the odd samples alone (one
    spike in zeros gives a "white noise" whose density depends only on the spike's size).
    """
    x = np.asarray(x, dtype=float)
    if x.size == 0:
        return "empty"
    m = float(np.median(x))
    n_diff = int(np.count_nonzero(x != m))
    if n_diff == 0:
        return f"constant ({m:g} in all {x.size} samples)"
    if n_diff < max(DEGENERATE_FRACTION * x.size, 3):
        return f"near-constant ({x.size - n_diff} of {x.size} samples are exactly {m:g}, {n_diff} differ)"
    return None


def check_axis_names(columns: Any) -> None:
    """Refuse ``NAME=COLUMN`` pairs whose NAME is not an IMU axis (a typo like ``gyro_w`` would be fitted
    and exported under a name no tool reads)."""
    from imunoise.io.tabular import parse_column_map

    cmap = parse_column_map(columns)
    if not isinstance(cmap, Mapping):
        return
    bad = [str(k) for k in cmap if str(k) not in AXES]
    if bad:
        raise DataError(f"--columns: unknown axis {bad[0]!r}; name the columns with the axes {', '.join(AXES)}")


GYRO_STATIC_MAX_MEAN = 0.1
"""rad/s (5.7 °/s): a static gyro's mean (Earth rate + bias) beyond this is not plausibly in rad/s."""

GYRO_STATIC_MAX_STD = 0.05
"""rad/s (2.9 °/s): a static gyro's per-sample σ beyond this is not plausibly in rad/s."""

ACCEL_STATIC_MAX_MEAN = 20.0
"""m/s² (2 g): a static accelerometer's mean beyond this is not plausibly in m/s²."""


def _check_unknown_units(series: ImuSeries) -> None:
    """Warn (:class:`UnitWarning`, also kept in ``series.meta["warnings"]``) when data without a unit
    cannot be SI (:func:`unknown_unit_messages`)."""
    unknown = [a for a in series.data if series.unit[a] == "u"]
    found = unknown_unit_messages(
        series.source,
        unknown,
        {a: float(np.mean(series.data[a])) for a in unknown},
        {a: float(np.std(series.data[a])) for a in unknown},
    )
    for msg in found:
        warnings.warn(msg, UnitWarning, stacklevel=3)
    if found:
        series.meta.setdefault("warnings", []).extend(found)


def unknown_unit_messages(
    source: str, unknown: Sequence[str], mean: Mapping[str, float], std: Mapping[str, float]
) -> list[str]:
    """Why axes given without a unit cannot be SI, from their static mean and σ: a static gyro with mean
    > 0.1 rad/s or σ > 0.05 rad/s is almost surely deg/s, three accelerometer means whose norm is ≈ 1 are
    in g. Without ``--units`` the values are taken as they are (unit "u"), and an export would turn them
    into rad/s or m/s² — wrong by 57× or 9.8×. One message per problem (empty when none)."""
    found: list[str] = []
    for axis in unknown:
        m, s = mean[axis], std[axis]
        kind = sensor_of(axis)
        if kind == "gyro" and (abs(m) > GYRO_STATIC_MAX_MEAN or s > GYRO_STATIC_MAX_STD):
            found.append(
                f"{source}: {axis} has no unit and a static mean {m:.3g} / σ {s:.3g} that cannot be "
                "rad/s (a still gyro stays below 0.1 rad/s); give --units deg/s (or the right unit)"
            )
        elif kind == "accel" and abs(m) > ACCEL_STATIC_MAX_MEAN:
            found.append(
                f"{source}: {axis} has no unit and a static mean {m:.4g} that cannot be m/s² "
                "(|g| = 9.81); give --units mg (or the right unit)"
            )
    acc = [a for a in unknown if sensor_of(a) == "accel"]
    if len(acc) == 3:
        g = float(np.linalg.norm([mean[a] for a in acc]))
        if 0.8 < g < 1.2:
            found.append(
                f"{source}: accelerometers {', '.join(acc)} have no unit and a static norm of {g:.3g}: "
                "that is 1 g, not 9.81 m/s²; give --units accel=g"
            )
    return found


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
