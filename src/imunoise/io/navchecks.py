"""Plausibility checks on the inputs of a navigation run (docs/guide/theory.rst, 'Interfaces'; issue "Bad input, second
round").

Each check turns a silently wrong run into a one-line :class:`~imunoise.errors.DataError` naming the file and
the fix, or into a warning kept in ``metrics.json``:

* :func:`check_gnss_llh` — latitudes outside ±90°, longitudes outside [−180°, 360°), and positions given in
  radians where degrees are expected. Read as degrees, radian values put the whole trajectory inside
  |lat|, |lon| < π° (≈ 350 km around 0° N 0° E, open sea in the Gulf of Guinea); read as radians the same
  numbers are an ordinary place on land. That box is the test.
* :func:`check_imu_gaps` — a time gap in the IMU longer than ``max_gap`` s: the strapdown mechanization would
  integrate one increment over it (docs/guide/theory.rst, 'Conventions' increments over (t_{k−1}, t_k]), and the
  velocity diverges.
* :func:`gyro_unit_evidence` — gyros recorded in °/s but read as rad/s turn 180/π ≈ 57× too fast: the heading
  change the gyros integrate (ψ̇ = (ω_y sin φ + ω_z cos φ)/cos θ, the Euler-rate kinematics of
  :mod:`imunoise.nav.align`) is compared with the course change of the GNSS track over the same epochs.
"""

from __future__ import annotations

import math

import numpy as np

from imunoise.errors import DataError

__all__ = [
    "RADIAN_BOX_DEG",
    "GYRO_TURN_RATIO_WARN",
    "check_gnss_llh",
    "check_imu_gaps",
    "gyro_unit_evidence",
]

RADIAN_BOX_DEG = math.pi
"""A GNSS file whose every |lat| and |lon| [deg] is below this reads as radians (module docstring)."""

GYRO_TURN_RATIO_WARN = 5.0
"""Gyro-integrated heading change / GNSS course change above this (or below its inverse) is warned: deg/s
read as rad/s gives ≈ 57.3."""

MIN_TURN_EVIDENCE_RAD = math.radians(90.0)
"""GNSS course change (in pieces turning more than :data:`TURN_PIECE_RAD`) needed before the ratio is judged."""

TURN_PIECE_RAD = math.radians(5.0)
"""A track piece whose course changes more than this is part of a turn."""


def check_gnss_llh(lat_deg: np.ndarray, lon_deg: np.ndarray, source: str, lines: np.ndarray | None = None) -> None:
    """Refuse GNSS positions that cannot be degrees of a real place: |lat| > 90°, lon outside [−180°, 360°),
    or every fix inside the ±π° box around 0° N 0° E (radians given where degrees are expected).

    Parameters
    ----------
    lat_deg, lon_deg : ndarray
        Latitudes and longitudes as read [deg].
    source : str
        The file (and topic) for the message.
    lines : ndarray, optional
        1-based file line of each fix, for the message.

    Raises
    ------
    DataError
        One line naming the file, the first bad value (and its line) and the fix.
    """
    lat = np.asarray(lat_deg, dtype=float)
    lon = np.asarray(lon_deg, dtype=float)
    if lat.size == 0:
        return
    for name, x, ok, rng in (
        ("latitude", lat, np.abs(lat) <= 90.0, "within ±90°"),
        ("longitude", lon, (lon >= -180.0) & (lon < 360.0), "within [−180°, 360°)"),
    ):
        if not ok.all():
            k = int(np.flatnonzero(~ok)[0])
            where = f", line {int(lines[k])}" if lines is not None else ""
            raise DataError(
                f"GNSS file {source}{where}: {name} {x[k]:g}° is not {rng} ({int((~ok).sum())} such fixes); "
                "the columns are t lat lon h [deg, deg, m]: check their order and unit"
            )
    if np.all(np.abs(lat) < RADIAN_BOX_DEG) and np.all(np.abs(lon) < RADIAN_BOX_DEG):
        raise DataError(
            f"GNSS file {source}: every latitude/longitude lies within ±π (lat {lat.min():.6g}..{lat.max():.6g}, "
            f"lon {lon.min():.6g}..{lon.max():.6g}): these are radians (as degrees, open sea off 0° N 0° E; as "
            f"radians {math.degrees(lat[0]):.4f}° N, {math.degrees(lon[0]):.4f}° E); the GNSS file takes degrees: "
            "multiply the lat and lon columns by 180/π"
        )


def check_imu_gaps(t: np.ndarray, max_gap: float, source: str, option: str = "--max-imu-gap") -> None:
    """Refuse IMU stamps with a step longer than ``max_gap`` s (module docstring).

    Raises
    ------
    DataError
        Naming the file, the gap's length and time, and the two ways out.
    """
    d = np.diff(np.asarray(t, dtype=float))
    if d.size == 0:
        return
    k = int(np.argmax(d))
    if d[k] > max_gap:
        n = int(np.count_nonzero(d > max_gap))
        raise DataError(
            f"IMU file {source}: a {d[k]:.3g} s time gap at t = {t[k]:.3f} s ({n} gap(s) longer than {max_gap:g} s); "
            f"the mechanization would integrate one increment across it: split the file at the gap, or pass "
            f"{option} {math.ceil(d[k] + 0.5):d} to integrate it as given"
        )


def gyro_unit_evidence(
    t: np.ndarray,
    gyro: np.ndarray,
    roll: float,
    pitch: float,
    bias: np.ndarray,
    gnss_t: np.ndarray,
    gnss_ned: np.ndarray,
    source: str,
    min_speed: float = 3.0,
    min_step_m: float = 5.0,
) -> str | None:
    """A warning when the gyros turn ≫ or ≪ the GNSS track (deg/s read as rad/s: ≈ 57×), else None.

    The GNSS track is cut into pieces of ≥ ``min_step_m`` travelled distance (so that the course of a piece is
    not position noise); between the middles of consecutive pieces both faster than ``min_speed``, the heading
    change of the bias-corrected gyros is regressed on the course change of the track (least-squares slope
    through 0, 1 for right units); judged once the track has turned by :data:`MIN_TURN_EVIDENCE_RAD`.

    Parameters
    ----------
    t, gyro : ndarray
        IMU epochs [s] and angular rates [rad/s as read], body FRD.
    roll, pitch : float
        Levelled attitude [rad] for the Euler-rate projection.
    bias : ndarray
        Static gyro mean [rad/s], removed first.
    gnss_t, gnss_ned : ndarray
        GNSS epochs [s] and antenna positions north/east/down [m] relative to any origin.
    source : str
        The IMU file, for the message.
    min_speed, min_step_m : float
        Pieces slower than this [m/s] are left out; the length of a piece [m] (≥ 30 σ_h of the fixes).

    Returns
    -------
    str or None
        The warning (with the measured ratio and the turn it rests on), or None.
    """
    t = np.asarray(t, dtype=float)
    w = np.asarray(gyro, dtype=float) - np.asarray(bias, dtype=float)
    psi_dot = (w[:, 1] * math.sin(roll) + w[:, 2] * math.cos(roll)) / math.cos(pitch)
    dt = np.diff(t, prepend=t[0])
    psi = np.cumsum(psi_dot * dt)
    gt = np.asarray(gnss_t, dtype=float)
    m = (gt >= t[0]) & (gt <= t[-1])
    gt, ned = gt[m], np.asarray(gnss_ned, dtype=float)[m, :2]
    if gt.size < 3:
        return None
    # track points every ≥ min_step_m of travelled distance: the course of each piece is then not GNSS noise
    path = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(ned, axis=0).T))])
    sel = np.flatnonzero(np.diff(np.floor(path / min_step_m), prepend=-1.0) > 0)
    if sel.size < 3:
        return None
    d = np.diff(ned[sel], axis=0)
    dt = np.diff(gt[sel])
    course = np.arctan2(d[:, 1], d[:, 0])
    speed = np.hypot(d[:, 0], d[:, 1]) / dt
    tmid = 0.5 * (gt[sel][1:] + gt[sel][:-1])
    moving = (speed[1:] > min_speed) & (speed[:-1] > min_speed)
    if not moving.any():
        return None
    d_course = np.angle(np.exp(1j * np.diff(course)))[moving]
    d_psi = np.diff(np.interp(tmid, t, psi))[moving]
    turning = np.abs(d_course) > TURN_PIECE_RAD  # the turns, not the course noise of straight driving
    turn_gnss = float(np.abs(d_course[turning]).sum())
    if turn_gnss < MIN_TURN_EVIDENCE_RAD:
        return None
    # least-squares slope of the gyro heading change on the GNSS course change (signed: noise averages out)
    ratio = float(np.dot(d_psi, d_course) / np.dot(d_course, d_course))
    turn_gyro = abs(ratio) * turn_gnss
    if 1.0 / GYRO_TURN_RATIO_WARN <= abs(ratio) <= GYRO_TURN_RATIO_WARN:
        return None
    guess = " (≈ 180/π: the gyros look like deg/s read as rad/s)" if 30.0 < abs(ratio) < 100.0 else ""
    return (
        f"IMU file {source}: the gyros turn {ratio:.3g}× the GNSS track (≈ {math.degrees(turn_gyro):.0f}° against "
        f"{math.degrees(turn_gnss):.0f}° of turns while moving){guess}; the navigation IMU takes rad "
        "(increments) or rad/s (rate CSV): convert the gyro columns"
    )
