"""Odometer files: ``t speed [σ]`` per line (the IMU's time base [s], vehicle speed, 1σ), whitespace or comma
separated, ``#`` comments, an optional header line; or a bag's twist topic (:mod:`imunoise.io.bag_twist`:
``TwistStamped`` / ``TwistWithCovarianceStamped`` / ``Odometry``, ``linear.x`` = forward speed in the vehicle frame).

:func:`read_odometer` returns checked speeds in m/s (:class:`SpeedFile`) or refuses the input in one line naming
it and the fix: a column count other than 2 or 3, a negative speed (a wheel-speed sensor is unsigned; leave
reversing out), a σ that is not positive, stamps out of order (a log written by two threads: sort it), stamps
in another time base than the IMU's, a unit other than m/s, km/h or mph, or speeds that are not the GNSS track's
(km/h given as m/s: 3.6×). Rows with NaN are dropped and counted (``SpeedFile.dropped``). ``scale`` divides out a
known scale factor (a calibration: z / scale).
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import NamedTuple

import numpy as np

from imunoise.errors import DataError
from imunoise.io.bag_topics import is_bag
from imunoise.io.bag_twist import read_twist_topic
from imunoise.io.files import is_number, read_text
from imunoise.io.gnss_velocity import check_time_base, track_speed_ratio

__all__ = ["SpeedFile", "read_odometer", "UNITS"]

UNITS = {"m/s": 1.0, "km/h": 1.0 / 3.6, "mph": 0.44704}
"""Speed units the reader converts to m/s."""


class SpeedFile(NamedTuple):
    """Odometer speeds: times [s] (sorted), speed [m/s], 1σ [m/s] (NaN where the file gives none), rows dropped
    for a NaN."""

    t: np.ndarray
    speed: np.ndarray
    sigma: np.ndarray
    dropped: int


def read_odometer(path: str | Path, *, unit: str = "m/s", scale: float = 1.0, imu_t: np.ndarray | None = None,
                  gnss=None, option: str = "--odometer", topic: str | None = None) -> SpeedFile:
    """Read and check an odometer file or bag topic (module docstring); ``unit`` of the speed column (and σ)
    (:data:`UNITS`), ``imu_t`` the IMU epochs [s] (the same time base), ``gnss`` position fixes (the speeds must
    be the track's), ``option`` the option that named the file (for the messages)."""
    path = Path(path)
    where = f"{path} ({option})"
    if unit not in UNITS:
        raise DataError(f"{where}: unit {unit!r} is not one of {', '.join(UNITS)}")
    if not (np.isfinite(scale) and scale > 0):
        raise DataError(f"{where}: scale factor {scale!r} must be a positive number (≈ 1)")
    if is_bag(path) and path.exists():
        tw = read_twist_topic(path, topic, option)
        d = np.column_stack([tw.t, tw.linear[:, 0], np.sqrt(tw.var[:, 0])])
    elif not path.is_file():
        raise DataError(f"{option}: no such file {path}")
    else:
        d = _table(path, where)
        if d.shape[1] not in (2, 3):
            raise DataError(f"{where}: {d.shape[1]} columns; expected 2 (t speed) or 3 (t speed σ)")
        if d.shape[1] == 2:
            d = np.column_stack([d, np.full(d.shape[0], np.nan)])
    t, v, s = d[:, 0], d[:, 1] * UNITS[unit] / scale, d[:, 2] * UNITS[unit]
    if np.any(v < 0):
        i = int(np.flatnonzero(v < 0)[0])
        raise DataError(f"{where}: negative speed {v[i]:.3f} m/s at row {i + 1} (t={t[i]:.3f}); an odometer speed "
                        "is unsigned: leave reversing out of the file")
    if np.any(s <= 0):
        i = int(np.flatnonzero(s <= 0)[0])
        raise DataError(f"{where}: σ {s[i]:g} m/s at row {i + 1} is not positive; give the sensor's 1σ or drop the "
                        "σ column")
    ok = np.isfinite(t) & np.isfinite(v)
    tt = t[ok]
    if np.any(np.diff(tt) < 0):
        i = int(np.flatnonzero(np.diff(tt) < 0)[0]) + 1
        raise DataError(f"{where}: time goes back at row {i + 1} ({tt[i]:.3f} after {tt[i - 1]:.3f} s); sort the "
                        "file by time")
    out = SpeedFile(np.ascontiguousarray(tt), np.ascontiguousarray(v[ok]), np.ascontiguousarray(s[ok]),
                    int(np.sum(~ok)))
    if out.t.size < 2:
        raise DataError(f"{where}: {out.t.size} finite speed(s); an odometer file needs a speed per epoch")
    if imu_t is not None:
        check_time_base(out.t, np.asarray(imu_t, dtype=float), where, "speeds")
    if gnss is not None:
        _check_track(out, gnss, where)
    return out


def _table(path: Path, where: str) -> np.ndarray:
    lines = [ln.split("#", 1)[0].replace(",", " ").strip() for ln in read_text(path, where).splitlines()]
    lines = [ln for ln in lines if ln]
    if lines and not all(is_number(x) for x in lines[0].split()):
        lines = lines[1:]  # a header
    if not lines:
        raise DataError(f"{where}: no data rows; expected t speed [σ] per line")
    try:
        return np.loadtxt(io.StringIO("\n".join(lines)), dtype=float, ndmin=2)
    except ValueError as exc:
        raise DataError(f"{where}: not a numeric table of t speed [σ] ({exc})") from exc


def _check_track(f: SpeedFile, gnss, where: str, min_speed: float = 3.0) -> None:
    """The median ratio of the speeds to the GNSS track's (:func:`~imunoise.io.gnss_velocity.track_speed_ratio`)
    must lie in [0.7, 1.4]; 3.6× is named as km/h."""
    ratio = track_speed_ratio(f.t, f.speed, gnss, min_speed)
    if ratio is None:
        return
    if 3.0 <= ratio <= 4.3:
        raise DataError(f"{where}: speeds are {ratio:.2f}× the GNSS track's: the values look like km/h; give the "
                        "unit (km/h) or divide by 3.6")
    if not 0.7 <= ratio <= 1.4:
        raise DataError(f"{where}: speeds are {ratio:.2f}× the GNSS track's; give the vehicle speed in m/s (or its "
                        "unit) in the IMU's time base")
