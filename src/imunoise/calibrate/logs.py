"""Reading the logs to calibrate from and their speed sources
(docs/guide/theory.rst, 'Static detection' and 'Online engine'; :mod:`imunoise.calibrate`)."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.errors import DataError
from imunoise.imu import AXES
from imunoise.io.imu_source import UNSET, ImuSource

GYRO_UNIT, ACCEL_UNIT = "rad/s", "m/s²"

# --------------------------------------------------------------------------------------------------
# inputs
# --------------------------------------------------------------------------------------------------
@dataclass(eq=False)
class ImuLog:
    """One moving IMU log in SI.

    Attributes
    ----------
    name : str
        Where it came from (for messages and the report).
    t : numpy.ndarray
        (n,) time [s], strictly increasing.
    gyro, accel : numpy.ndarray
        (n, 3) angular rate [rad/s] and specific force [m/s²], body axes x, y, z (x, y horizontal when level).
    rate_hz : float
        Nominal sample rate [Hz].
    speed : tuple of numpy.ndarray, optional
        (t [s], speed [m/s]) of a reference or GNSS in the same time base, for the stop check and the plot.
    meta : dict
        Source details (format, topic, warnings).
    span_s : tuple of float, optional
        (first, last) stamp [s] of a streamed log (:func:`stream_stops`), whose ``t`` is its per-second grid
        and whose ``gyro``/``accel`` are empty.
    """

    name: str
    t: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray
    rate_hz: float
    speed: tuple[np.ndarray, np.ndarray] | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    span_s: tuple[float, float] | None = None

    @property
    def duration_s(self) -> float:
        if self.span_s is not None:
            return float(self.span_s[1] - self.span_s[0])
        return float(self.t[-1] - self.t[0])


def speed_of_reference(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    from imunoise.io.kfgins import read_reference

    ref = read_reference(path)
    return np.asarray(ref.t, dtype=float), np.linalg.norm(np.asarray(ref.vel_ned)[:, :2], axis=1)


def speed_of_gnss(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal speed [m/s] from successive GNSS positions (local spherical Earth: metres per radian = R)."""
    from imunoise.io.navinput import read_nav_gnss

    g = read_nav_gnss(path)
    t = np.asarray(g.t, dtype=float)
    if t.size < 2:
        raise DataError(f"GNSS file {path}: fewer than 2 epochs, no speed can be formed")
    lat, lon = g.llh[:, 0], g.llh[:, 1]
    r = 6_371_000.0
    dn = np.diff(lat) * r
    de = np.diff(lon) * r * np.cos(0.5 * (lat[1:] + lat[:-1]))
    v = np.hypot(dn, de) / np.diff(t)
    return 0.5 * (t[1:] + t[:-1]), v


def read_log(
    path: str | Path | ImuSource,
    *,
    topic: str | None = UNSET,
    columns: str | Sequence[str | int] | Mapping[str, str | int] | None = UNSET,
    units: str | Mapping[str, str] | None = UNSET,
    time_column: str | int | None = UNSET,
    time_unit: str | None = UNSET,
    freq: float | None = UNSET,
    ref: str | Path | None = None,
    gnss: str | Path | None = None,
) -> ImuLog:
    """Read one moving log into an :class:`ImuLog` (SI, six axes).

    Parameters
    ----------
    path : str, Path or ImuSource
        An :class:`~imunoise.io.imu_source.ImuSource` (with the reader settings below), or a ROS bag (``.bag``,
        ``.db3``, ``.mcap``, ROS 2 folder; all six axes of ``topic``), a dataset folder with ``dataset.json``
        (its IMU, and its reference for the speed), a KF-GINS IMU file (increments, or a rate CSV with
        ``sow,gx,..,az``), or a table/.npz whose columns map to ``gyro_x`` .. ``accel_z``.
    topic : str, optional
        Bag topic.
    columns, units, time_column, time_unit, freq
        As for :func:`imunoise.io.imu_input.read_imu_source` (tables): the six axes must be named. Not given:
        the :class:`~imunoise.io.imu_source.ImuSource` defaults (or the fields of ``path`` when it is one).
    ref, gnss : str or Path, optional
        A KF-GINS reference (speed from its velocity) or a GNSS file (KF-GINS, RTKLIB .pos, bag; speed from
        successive positions), same time base as the IMU.

    Returns
    -------
    ImuLog
    """
    from imunoise.io.rosbag import is_bag

    src = ImuSource.of(path, topic=topic, columns=columns, units=units, time_column=time_column,
                       time_unit=time_unit, freq=freq)
    p = Path(src.path)
    speed = None
    meta: dict[str, Any] = {}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if p.is_dir() and (p / "dataset.json").exists():
            from imunoise.io.dataset import read_dataset
            from imunoise.io.kfgins import read_imu

            ds = read_dataset(p, required=("imu",))
            unit = src.time_unit or "s"
            imu = read_imu(ds.imu, time_offset=float(ds.imu_time_offset_s or 0.0), time_unit=unit)
            check_stamp_unit(imu.t, unit, f"IMU file {ds.imu}")
            gyro, accel = imu.rates()
            t, rate = np.asarray(imu.t, dtype=float), float(imu.rate_hz)
            meta["format"] = "dataset"
            if ref is None and gnss is None and ds.ref:
                ref = ds.ref
            elif ref is None and gnss is None and getattr(ds, "gnss", None):
                gnss = ds.gnss
        elif is_bag(p) or src.columns is not None or p.suffix.lower() in (".npz", ".npy"):
            t, gyro, accel, rate, meta = _read_source(src)
        else:
            from imunoise.io.kfgins import read_imu

            unit = src.time_unit or "s"
            imu = read_imu(p, time_unit=unit)
            check_stamp_unit(imu.t, unit, f"IMU file {p}")
            gyro, accel = imu.rates()
            t, rate = np.asarray(imu.t, dtype=float), float(imu.rate_hz)
            meta["format"] = "kfgins"
        if ref is not None:
            speed = speed_of_reference(ref)
            meta["speed_from"] = f"reference {ref}"
        elif gnss is not None:
            speed = speed_of_gnss(gnss)
            meta["speed_from"] = f"GNSS {gnss}"
    msgs = list(dict.fromkeys(str(w.message) for w in caught))
    if msgs:
        meta["warnings"] = msgs
    name = str(src.path)  # as given (a folder keeps its slash)
    return ImuLog(name, t, np.ascontiguousarray(gyro), np.ascontiguousarray(accel), rate, speed, meta)


def check_stamp_unit(t: np.ndarray, unit: str, source: str) -> None:
    """Refuse stamps read in ``unit`` [converted to s in ``t``] whose spacing is no IMU rate while another unit
    gives one (milliseconds read as seconds: 0.1 Hz with "gaps" of seconds), naming ``--time-unit``: the rule
    `fit`'s table readers apply (:func:`imunoise.io.time_column.infer_time_unit`), for the KF-GINS files."""
    from imunoise.io.time_column import infer_time_unit
    from imunoise.units import TIME_UNITS

    dt = np.diff(t)
    dt = dt[dt > 0]
    if dt.size:
        infer_time_unit(float(np.median(dt)) / TIME_UNITS[unit], unit, source)


def _read_source(src: ImuSource):
    from imunoise.io.imu_input import read_imu_source

    p = Path(src.path)
    s = read_imu_source(src)
    missing = [a for a in AXES if a not in s.data]
    if missing:
        raise DataError(
            f"{p}: calibrate needs all six axes, {', '.join(missing)} missing (have {', '.join(s.data)}); map "
            "them with --columns gyro_x=COL,...,accel_z=COL and give --units gyro=...,accel=..."
        )
    for a in AXES:
        want = GYRO_UNIT if a.startswith("gyro") else ACCEL_UNIT
        if s.unit[a] not in (want, "m/s2", "m/s^2") and not (want == ACCEL_UNIT and s.unit[a] in ("m/s2",)):
            raise DataError(f"{p}: axis {a} is in {s.unit[a]!r}, not {want}; give --units gyro=...,accel=...")
    n = len(s)
    t = np.asarray(s.t, dtype=float) if s.t is not None else np.arange(n) / float(s.freq)
    gyro = np.column_stack([s.data[a] for a in AXES[:3]])
    accel = np.column_stack([s.data[a] for a in AXES[3:]])
    meta = {k: v for k, v in s.meta.items() if k in ("format", "topic", "frame_id", "frame")}
    return t, gyro, accel, float(s.freq), meta
