"""GPS time for the navigation inputs: every navigation run works in GPS seconds of week (GPST), the time base
of the KF-GINS files (docs/guide/theory.rst, 'Interfaces'). ROS stamps are Unix time (UTC, REP 103 / ``ros::Time``) and
RTKLIB solutions may be written in UTC or JST; these helpers bring them to GPST.

GPST − UTC is the number of leap seconds inserted since the GPS epoch (1980-01-06 00:00 UTC), from the IERS
bulletins; it has been 18 s since 2017-01-01. A recording crossing a leap second is converted with the value
at its first epoch (the one second would otherwise split one run into two time bases).
"""

from __future__ import annotations

import calendar

import numpy as np

__all__ = [
    "GPS_EPOCH_UNIX",
    "SECONDS_PER_WEEK",
    "UNIX_STAMP_MIN_S",
    "gps_minus_utc",
    "utc_to_gps_seconds",
    "unix_ns_to_gps_ns",
    "gps_week",
]

GPS_EPOCH_UNIX = 315_964_800
"""1980-01-06 00:00:00 UTC as Unix seconds (no leap seconds had been inserted into GPST yet)."""

SECONDS_PER_WEEK = 604_800

UNIX_STAMP_MIN_S = 1e9
"""Stamps at or above this many seconds (2001-09-09) are read as Unix time; smaller ones as already in the
data's own time base (GPS seconds of week, or a clock since power-up)."""

# (Unix time of the first second with the new offset, GPST − UTC in s after it): IERS Bulletin C.
_LEAPS = (
    (calendar.timegm((1981, 7, 1, 0, 0, 0)), 1),
    (calendar.timegm((1982, 7, 1, 0, 0, 0)), 2),
    (calendar.timegm((1983, 7, 1, 0, 0, 0)), 3),
    (calendar.timegm((1985, 7, 1, 0, 0, 0)), 4),
    (calendar.timegm((1988, 1, 1, 0, 0, 0)), 5),
    (calendar.timegm((1990, 1, 1, 0, 0, 0)), 6),
    (calendar.timegm((1991, 1, 1, 0, 0, 0)), 7),
    (calendar.timegm((1992, 7, 1, 0, 0, 0)), 8),
    (calendar.timegm((1993, 7, 1, 0, 0, 0)), 9),
    (calendar.timegm((1994, 7, 1, 0, 0, 0)), 10),
    (calendar.timegm((1996, 1, 1, 0, 0, 0)), 11),
    (calendar.timegm((1997, 7, 1, 0, 0, 0)), 12),
    (calendar.timegm((1999, 1, 1, 0, 0, 0)), 13),
    (calendar.timegm((2006, 1, 1, 0, 0, 0)), 14),
    (calendar.timegm((2009, 1, 1, 0, 0, 0)), 15),
    (calendar.timegm((2012, 7, 1, 0, 0, 0)), 16),
    (calendar.timegm((2015, 7, 1, 0, 0, 0)), 17),
    (calendar.timegm((2017, 1, 1, 0, 0, 0)), 18),
)


def gps_minus_utc(unix_s: float) -> int:
    """GPST − UTC [s] at the UTC instant ``unix_s`` (Unix seconds): the leap seconds since 1980-01-06."""
    out = 0
    for start, leap in _LEAPS:
        if unix_s >= start:
            out = leap
    return out


def utc_to_gps_seconds(unix_s: np.ndarray) -> np.ndarray:
    """UTC as Unix seconds → GPS seconds since the GPS epoch, with the leap seconds at the first epoch."""
    unix_s = np.asarray(unix_s, dtype=float)
    leap = gps_minus_utc(float(unix_s.flat[0])) if unix_s.size else 0
    return unix_s - GPS_EPOCH_UNIX + leap


def unix_ns_to_gps_ns(unix_ns: np.ndarray) -> tuple[np.ndarray, int]:
    """Unix (UTC) stamps in integer ns → GPS ns since the GPS epoch, exactly (integer arithmetic, so a 100 Hz
    stamp keeps its ns); also returns the leap seconds used (those at the first stamp)."""
    unix_ns = np.asarray(unix_ns, dtype=np.int64)
    leap = gps_minus_utc(float(unix_ns[0]) * 1e-9) if unix_ns.size else 0
    return unix_ns - np.int64(GPS_EPOCH_UNIX - leap) * 1_000_000_000, leap


def gps_week(gps_s: float) -> int:
    """GPS week of an instant given as GPS seconds since the GPS epoch."""
    return int(gps_s // SECONDS_PER_WEEK)
