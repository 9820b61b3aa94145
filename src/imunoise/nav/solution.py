"""Derived quantities of a navigation solution shared by the batch and the online results
(docs/guide/theory.rst, 'Navigation filter')."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from imunoise.nav.earth import radii

__all__ = ["antenna_llh", "NavSolution"]


@dataclass
class NavSolution:
    """The solution at every processed IMU epoch (IMU point) that the batch :class:`imunoise.nav.ekf.EkfResult`
    and the online :class:`imunoise.online.OnlineResult` share (docs/guide/theory.rst, 'Navigation filter'): ``t`` [s],
    ``llh`` [rad, rad, m],
    ``vel_ned`` [m/s], ``euler`` roll, pitch, yaw [rad], the total estimated sensor errors ``gyro_error``
    [rad/s] and ``accel_error`` [m/s²], ``std`` the 1σ of [δr (NED), δv, φ]."""

    t: np.ndarray
    llh: np.ndarray
    vel_ned: np.ndarray
    euler: np.ndarray
    gyro_error: np.ndarray
    accel_error: np.ndarray
    std: np.ndarray

    def antenna_llh(self, lever_arm: Sequence[float]) -> np.ndarray:
        """Positions of the point at ``lever_arm`` (body FRD, m) from the IMU, e.g. the GNSS antenna
        (:func:`antenna_llh`)."""
        return antenna_llh(self.llh, self.euler, lever_arm)


def antenna_llh(llh: np.ndarray, euler: np.ndarray, lever_arm: Sequence[float]) -> np.ndarray:
    """Positions of the point at ``lever_arm`` (body FRD, m) from the IMU, e.g. the GNSS antenna.

    r_ant = r_imu + D_R⁻¹ C_b^n l with C_b^n from the ZYX Euler angles (:func:`imunoise.nav.earth.euler_to_dcm`)
    and D_R⁻¹ = diag(1/(R_M + h), 1/((R_N + h) cos φ), −1) evaluated at the IMU point, the inverse of the
    lever-arm term of the GNSS measurement model (docs/guide/theory.rst, 'Navigation filter'); the first-order
    conversion errs by ~|l|²/R (2e-7 m for a 1 m arm).

    Parameters
    ----------
    llh : numpy.ndarray
        (n, 3) IMU positions: latitude, longitude (rad), ellipsoidal height (m).
    euler : numpy.ndarray
        (n, 3) roll, pitch, yaw (rad) of C_b^n.
    lever_arm : Sequence[float]
        The point in the body frame (forward, right, down) from the IMU, m.

    Returns
    -------
    numpy.ndarray
        (n, 3) positions of the point (a copy of ``llh`` when the arm is zero).
    """
    lever = np.asarray(lever_arm, dtype=float)
    llh = np.asarray(llh, dtype=float)
    euler = np.asarray(euler, dtype=float)
    out = llh.copy()
    if not np.any(lever):
        return out
    r, p, y = euler[:, 0], euler[:, 1], euler[:, 2]
    sr, cr, sp, cp, sy, cy = np.sin(r), np.cos(r), np.sin(p), np.cos(p), np.sin(y), np.cos(y)
    # d = C_b^n(roll, pitch, yaw) · lever, rows of the ZYX matrix of :func:`earth.euler_to_dcm`
    d_n = cp * cy * lever[0] + (-cr * sy + sr * sp * cy) * lever[1] + (sr * sy + cr * sp * cy) * lever[2]
    d_e = cp * sy * lever[0] + (cr * cy + sr * sp * sy) * lever[1] + (-sr * cy + cr * sp * sy) * lever[2]
    d_d = -sp * lever[0] + sr * cp * lever[1] + cr * cp * lever[2]
    rm, rn = radii(llh[:, 0])
    out[:, 0] += d_n / (rm + llh[:, 2])
    out[:, 1] += d_e / ((rn + llh[:, 2]) * np.cos(llh[:, 0]))
    out[:, 2] -= d_d
    return out
