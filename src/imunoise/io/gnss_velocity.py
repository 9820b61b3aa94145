"""GNSS velocity files: ``t vN vE vD [σN σE σD]`` per line (GPS seconds of week, NED m/s, 1σ m/s), whitespace or
comma separated, ``#`` comments, an optional header line (data/drive_0708/gnss_rtk_vel.txt is one).

:func:`read_gnss_velocity` returns checked fixes (:class:`VelocityFile`; the filter takes them through
:func:`imunoise.nav.measurements.gnss_velocity.as_gnss_velocity`) or refuses the file in one line naming it and
the fix: a column count other than 4 or 7, a negative or zero σ (a receiver's σ is positive; a 0 would make the
filter certain), stamps in another time base than the IMU's (Unix seconds against GPS seconds of week, or no
overlap), speeds that are not the GNSS track's (km/h: 3.6× the speed of the position fixes; or another unit).
Rows with NaN are dropped and counted (``VelocityFile.dropped``; ``nav`` writes the count to metrics.json).
A bag (:func:`imunoise.io.bag_topics.is_bag`) is read from its twist topic (:mod:`imunoise.io.bag_twist`:
``TwistWithCovarianceStamped`` / ``TwistStamped`` in ENU as REP 103 and the u-blox driver publish it; σ from the
covariance's diagonal where given), with the same checks.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import NamedTuple

import numpy as np

from imunoise.errors import DataError
from imunoise.io.bag_topics import is_bag
from imunoise.io.bag_twist import read_twist_topic
from imunoise.io.files import read_text

__all__ = ["VelocityFile", "read_gnss_velocity", "check_velocity_track", "check_time_base", "track_speed_ratio",
           "UNIX_T0"]


class VelocityFile(NamedTuple):
    """The fixes of a velocity file: times [s] (sorted), NED velocity [m/s] (n, 3), 1σ NED [m/s] (n, 3), and the
    number of rows dropped for a NaN."""

    t: np.ndarray
    vel_ned: np.ndarray
    sigma_ned: np.ndarray
    dropped: int

UNIX_T0 = 1.0e8
"""Stamps above this [s] are Unix time (2003 onwards), not GPS seconds of week (< 604 800)."""


def _table(path: Path, option: str) -> np.ndarray:
    text = read_text(path, f"GNSS velocity file ({option})")
    lines = [ln.split("#", 1)[0].replace(",", " ").strip() for ln in text.splitlines()]
    lines = [ln for ln in lines if ln]
    if lines and not all(_number(x) for x in lines[0].split()):
        lines = lines[1:]  # a header
    if not lines:
        raise DataError(f"{path} ({option}): no data rows; expected t vN vE vD [σN σE σD] per line")
    try:
        data = np.loadtxt(io.StringIO("\n".join(lines)), dtype=float, ndmin=2)
    except ValueError as exc:
        raise DataError(f"{path} ({option}): not a numeric table of t vN vE vD [σN σE σD] ({exc})") from exc
    return data


def _number(x: str) -> bool:
    try:
        float(x)
    except ValueError:
        return False
    return True


def read_gnss_velocity(path: str | Path, *, sigma: float | None = None, imu_t: np.ndarray | None = None,
                       gnss=None, option: str = "--gnss-vel", topic: str | None = None) -> VelocityFile:
    """Read and check a GNSS velocity file (module docstring).

    Parameters
    ----------
    path : str or Path
        The file.
    sigma : float, optional
        1σ [m/s] for a file with four columns (no σ); default 0.05 m/s.
    imu_t : numpy.ndarray, optional
        IMU epochs [s]: the fixes must share their time base.
    gnss : GnssData, optional
        Position fixes: the speeds must be the track's (:func:`check_velocity_track`).
    option : str
        The option that named the file (for the messages).
    topic : str, optional
        The twist topic of a bag (default: its only twist topic).
    """
    path = Path(path)
    if is_bag(path) and path.exists():
        tw = read_twist_topic(path, topic, option)
        # ENU → NED; σ from the covariance, else the default
        d = np.column_stack([tw.t, tw.linear[:, 1], tw.linear[:, 0], -tw.linear[:, 2],
                             np.sqrt(tw.var[:, [1, 0, 2]])])
        d[:, 4:7] = np.where(np.isnan(d[:, 4:7]), 0.05 if sigma is None else float(sigma), d[:, 4:7])
        return _checked(d, path, option, imu_t, gnss)
    if not path.is_file():
        raise DataError(f"{option}: no such file {path}")
    return _checked(_table(path, option), path, option, imu_t, gnss, sigma)


def _checked(d: np.ndarray, path: Path, option: str, imu_t, gnss, sigma: float | None = None) -> VelocityFile:
    if d.shape[1] not in (4, 7):
        raise DataError(f"{path} ({option}): {d.shape[1]} columns; expected 4 (t vN vE vD) or 7 (t vN vE vD σN σE σD)")
    s = d[:, 4:7] if d.shape[1] == 7 else np.full((d.shape[0], 3), 0.05 if sigma is None else float(sigma))
    if np.any(s <= 0):
        i = int(np.flatnonzero(np.any(s <= 0, axis=1))[0])
        raise DataError(f"{path} ({option}): σ {s[i].tolist()} m/s at row {i + 1} (t={d[i, 0]:.3f}) is not positive; "
                        "give the receiver's 1σ (m/s) or drop the σ columns")
    ok = np.all(np.isfinite(d[:, :4]), axis=1) & np.all(np.isfinite(s), axis=1)
    order = np.argsort(d[ok, 0], kind="stable")
    vel = VelocityFile(np.ascontiguousarray(d[ok, 0][order]), np.ascontiguousarray(d[ok, 1:4][order]),
                       np.ascontiguousarray(s[ok][order]), int(np.sum(~ok)))
    if imu_t is not None and vel.t.size:
        check_time_base(vel.t, np.asarray(imu_t, dtype=float), f"{path} ({option})")
    if gnss is not None:
        check_velocity_track(vel, gnss, f"{path} ({option})")
    return vel


def check_time_base(t: np.ndarray, imu_t: np.ndarray, what: str, noun: str = "fixes") -> None:
    """Refuse stamps ``t`` of an aiding file (``what``: its name in the message; ``noun``: what its rows are)
    that are Unix time against an IMU in GPS seconds of week, or that do not overlap the IMU at all."""
    if t[0] > UNIX_T0 and imu_t[-1] < UNIX_T0:
        raise DataError(f"{what}: stamps {t[0]:.0f} s look like Unix time while the IMU is in GPS seconds "
                        f"of week ({imu_t[0]:.0f}–{imu_t[-1]:.0f} s); convert them to GPS seconds of week")
    if t[-1] < imu_t[0] or t[0] > imu_t[-1]:
        raise DataError(f"{what}: {noun} {t[0]:.1f}–{t[-1]:.1f} s do not overlap the IMU "
                        f"{imu_t[0]:.1f}–{imu_t[-1]:.1f} s; use the IMU's time base")


def track_speed_ratio(t: np.ndarray, speed: np.ndarray, gnss, min_speed: float = 3.0) -> float | None:
    """The median ratio of the horizontal ``speed`` at ``t`` to the speed of the GNSS position fixes' track (finite
    differences) where the track is faster than ``min_speed`` (m/s); None with fewer than 3 finite fixes or 5
    moving epochs (too little to judge)."""
    gt, llh = np.asarray(gnss.t, dtype=float), np.asarray(gnss.llh, dtype=float)
    ok = np.isfinite(gt) & np.all(np.isfinite(llh), axis=1)
    gt, llh = gt[ok], llh[ok]
    if gt.size < 3:
        return None
    r = 6378137.0 + llh[1:, 2]  # a sphere: the ratio test needs 1 %, the Earth's radii differ by < 0.7 %
    dn = np.diff(llh[:, 0]) * r
    de = np.diff(llh[:, 1]) * r * np.cos(llh[1:, 0])
    dt = np.diff(gt)
    good = dt > 0
    tm = 0.5 * (gt[1:] + gt[:-1])[good]
    track = np.hypot(dn, de)[good] / dt[good]
    inside = (t > tm[0]) & (t < tm[-1])
    sp_track = np.interp(t[inside], tm, track)
    moving = sp_track > min_speed
    if moving.sum() < 5:
        return None
    return float(np.median(speed[inside][moving] / sp_track[moving]))


def check_velocity_track(vel: VelocityFile, gnss, what: str, min_speed: float = 3.0) -> None:
    """Refuse velocities whose horizontal speed is not the GNSS track's: the median ratio of |v_h| to the speed of
    the position fixes (:func:`track_speed_ratio`) must lie in [0.7, 1.4]; 3.6× is named as km/h."""
    if vel.t.size < 3:
        return
    ratio = track_speed_ratio(vel.t, np.hypot(vel.vel_ned[:, 0], vel.vel_ned[:, 1]), gnss, min_speed)
    if ratio is None:
        return
    if 3.0 <= ratio <= 4.3:
        raise DataError(f"{what}: speeds are {ratio:.2f}× the GNSS track's: the values look like km/h; divide by 3.6 "
                        "(velocities in m/s, NED)")
    if not 0.7 <= ratio <= 1.4:
        raise DataError(f"{what}: speeds are {ratio:.2f}× the GNSS track's; give NED velocity in m/s of the same "
                        "antenna")
