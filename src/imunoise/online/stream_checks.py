"""Checks of what the streaming API of :class:`~imunoise.online.navigator.OnlineNavigator` is given: one GNSS
fix (:meth:`push_gnss`) and one IMU increment (:meth:`push_imu`); each error names the argument and the fix."""

from __future__ import annotations

import math

import numpy as np

from imunoise.errors import DataError

__all__ = ["check_fix", "check_increment", "fixes_pass"]


def check_fix(t, llh_rad, sigma_ned_m) -> tuple[float, np.ndarray, np.ndarray]:
    """(t s, llh rad/rad/m, σ NED m) of one fix, copied; :class:`DataError` for non-numbers, wrong shapes,
    non-finite positions, degrees and negative σ (NaN σ passes: the filter replaces it)."""
    try:
        t = float(t)
    except (TypeError, ValueError) as exc:
        raise DataError(f"push_gnss: time must be a number of seconds, got {t!r}") from exc
    llh = np.asarray(llh_rad, dtype=float).reshape(-1).copy()
    sig = np.asarray(sigma_ned_m, dtype=float).reshape(-1).copy()
    if llh.size != 3 or sig.size != 3:
        raise DataError(
            f"push_gnss: llh_rad must be (lat rad, lon rad, h m) and sigma_ned_m 3 values (m), got "
            f"{np.shape(llh_rad)} and {np.shape(sigma_ned_m)}"
        )
    if not (math.isfinite(t) and np.all(np.isfinite(llh))):
        raise DataError(
            f"push_gnss: non-finite fix (t={t!r}, llh_rad={llh.tolist()}); skip fixes without a position"
        )
    if abs(llh[0]) > math.pi / 2 or abs(llh[1]) > math.pi:
        raise DataError(
            f"push_gnss: latitude {llh[0]!r}, longitude {llh[1]!r} cannot be radians (|lat| ≤ π/2, |lon| ≤ π); "
            "they look like degrees: convert with np.radians(lat), np.radians(lon)"
        )
    if np.any(sig < 0):
        raise DataError(f"push_gnss: sigma_ned_m must be ≥ 0 m (1σ per axis), got {sig.tolist()}")
    return t, llh, sig


def fixes_pass(gt, gllh, gsig) -> bool:
    """True when every fix of a record (times, (m, 3) llh, (m, 3) σ) passes :func:`check_fix` (numbers, (3,)
    position and σ, finite time and position, radians, σ ≥ 0 or NaN): the same tests on the whole arrays, so a
    replay checks its record once (:func:`imunoise.online.chunks.run_record`)."""
    try:
        t = np.asarray(gt, dtype=float).reshape(-1)
        llh = np.asarray(gllh, dtype=float)
        sig = np.asarray(gsig, dtype=float)
    except (TypeError, ValueError):
        return False
    if llh.shape != (t.size, 3) or sig.shape != (t.size, 3):
        return False
    return bool(np.all(np.isfinite(t)) and np.all(np.isfinite(llh)) and np.all(np.abs(llh[:, 0]) <= math.pi / 2)
                and np.all(np.abs(llh[:, 1]) <= math.pi) and not np.any(sig < 0))


def check_increment(t, dtheta, dv, t_in: float) -> tuple[float, np.ndarray, np.ndarray]:
    """(t s, Δθ rad, Δv m/s) of one IMU increment after the sample at ``t_in``; :class:`DataError` for a
    non-number, a stamp that does not increase, or shapes other than (3,)."""
    try:
        t = float(t)
    except (TypeError, ValueError) as exc:
        raise DataError(f"push_imu: time must be a number of seconds, got {t!r}") from exc
    if not t > t_in:
        raise DataError(f"push_imu: time {t!r} does not follow {t_in!r}; stamps must increase")
    dth = np.asarray(dtheta, dtype=float)
    dvv = np.asarray(dv, dtype=float)
    if dth.shape != (3,) or dvv.shape != (3,):
        raise DataError(
            f"push_imu: dtheta and dv must be 3 increments each (x, y, z; rad and m/s), got shapes "
            f"{dth.shape} and {dvv.shape}"
        )
    return t, dth, dvv
