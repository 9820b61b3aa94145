"""GNSS antenna velocity (Doppler or RTK velocity; ROS ``TwistStamped``, RTKLIB velocity output).

The antenna moves with v^n + C_b^n (ω_ib^b × l) for the lever arm l (body FRD, m; the Earth-rate part of
ω_eb^b, < 1e-5 m/s for l < 0.1 m, is left out). With Ĉ = (I − φ×)C, u = Ĉ(ω̂ × l):

    dz = v̂^n + u − z,     H = [0, I, (u×), 0],     R = diag(σ²)

ω̂ is the last corrected increment Δθ̂/Δt; the gyro-bias coupling of the lever term (|l|·δb, below 1e-6 m/s
for a 0.1 m lever and a 10 °/h bias) and the acceleration between the fix and the filter epoch (≤ one IMU
interval) are left out. The fix goes through the χ² gate of
:func:`~imunoise.nav.ekf_kernels.kf_update` with ``EkfConfig.chi2_gate`` (3 dof).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from imunoise.errors import DataError
from imunoise.nav.mechanization import quat_to_dcm
from imunoise.nav.state import I_DTH, I_Q, I_VEL, X_ATT, X_VEL

__all__ = ["GnssVelocity", "gnss_velocity", "as_gnss_velocity"]


class GnssVelocity(NamedTuple):
    """Velocity fixes of the GNSS antenna: times [s] (the IMU time base), NED velocity [m/s] (n, 3), 1σ NED
    [m/s] (n, 3)."""

    t: np.ndarray
    vel_ned: np.ndarray
    sigma_ned: np.ndarray


def as_gnss_velocity(t, vel_ned, sigma_ned, *, sigma_floor: float = 0.005) -> GnssVelocity:
    """Checked, sorted fixes with finite values; σ below ``sigma_floor`` (m/s) raised to it (a 0 σ would make
    the filter certain)."""
    t = np.asarray(t, dtype=float).ravel()
    v = np.asarray(vel_ned, dtype=float).reshape(-1, 3)
    s = np.broadcast_to(np.asarray(sigma_ned, dtype=float), v.shape).copy()
    if not (t.size == v.shape[0] == s.shape[0]):
        raise DataError(f"GNSS velocity: {t.size} times, {v.shape[0]} velocities and {s.shape[0]} σ rows differ")
    ok = np.isfinite(t) & np.all(np.isfinite(v), axis=1) & np.all(np.isfinite(s), axis=1)
    order = np.argsort(t[ok], kind="stable")
    return GnssVelocity(np.ascontiguousarray(t[ok][order]), np.ascontiguousarray(v[ok][order]),
                        np.ascontiguousarray(np.maximum(s[ok][order], sigma_floor)))


@njit(cache=True)
def gnss_velocity(nav, n, z_vel, lever, dt, sigma):
    """(dz (3,), H (3, n), R (3, 3)) of an antenna velocity ``z_vel`` (NED m/s) with 1σ ``sigma``; ``dt`` is
    the interval of the last increment (for ω̂)."""
    C = quat_to_dcm(nav[I_Q : I_Q + 4])
    w = np.empty(3)
    for i in range(3):
        w[i] = nav[I_DTH + i] / dt if dt > 0.0 else 0.0
    a = np.array([w[1] * lever[2] - w[2] * lever[1], w[2] * lever[0] - w[0] * lever[2],
                  w[0] * lever[1] - w[1] * lever[0]])
    u = np.zeros(3)
    for i in range(3):
        for j in range(3):
            u[i] += C[i, j] * a[j]
    dz = np.empty(3)
    H = np.zeros((3, n))
    R = np.zeros((3, 3))
    for i in range(3):
        dz[i] = nav[I_VEL + i] + u[i] - z_vel[i]
        H[i, X_VEL + i] = 1.0
        R[i, i] = sigma[i] * sigma[i]
    # (u×)
    H[0, X_ATT + 1] = -u[2]
    H[0, X_ATT + 2] = u[1]
    H[1, X_ATT] = u[2]
    H[1, X_ATT + 2] = -u[0]
    H[2, X_ATT] = -u[1]
    H[2, X_ATT + 1] = u[0]
    return dz, H, R
