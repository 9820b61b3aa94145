"""GNSS antenna velocity (Doppler or RTK velocity; ROS ``TwistStamped``, RTKLIB velocity output).

The antenna moves with v^n + C_b^n (ω_ib^b × l) for the lever arm l (body FRD, m; the Earth-rate part of
ω_eb^b, < 1e-5 m/s for l < 0.1 m, is left out). With Ĉ = (I − φ×)C, u = Ĉ(ω̂ × l):

    dz = v̂^n + u − z,     H = [0, I, (u×), 0],     R = diag(σ²)

ω̂ is the last corrected increment Δθ̂/Δt; the gyro-bias coupling of the lever term (|l|·δb, below 1e-6 m/s
for a 0.1 m lever and a 10 °/h bias) and the acceleration between the fix and the filter epoch (≤ one IMU
interval) are left out.

The gate. A fix goes through the χ² gate of :func:`~imunoise.nav.ekf_kernels.kf_update` with
``EkfConfig.chi2_gate`` (3 dof), with two guards of robust filters, as the GNSS position gate has them:
innovations of the order of ``gate_abs`` (default :data:`VEL_GATE_ABS` = 0.1 m/s, added squared to S in the
test) are never outliers whatever σ the receiver claims, and after ``max_reject`` (default
:data:`VEL_MAX_REJECT` = 10, 2.5 s at 4 Hz) consecutive rejections the next fix is forced in. Without them the
RTK velocity of data/drive_0708 (σ 4–6 cm/s) was rejected all through its 60 s position outages, exactly when it
is the only aiding: the filter's velocity error then exceeds a few σ of the fix while P, with a model of the
consumer IMU that is only approximate, does not grow as fast (measured on that drive's five outages,
``docs/evidence/gnss_velocity.md``: mean end error 280 m with the plain gate, 0.56 m with these guards).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from imunoise.errors import DataError
from imunoise.nav.mechanization import quat_to_dcm
from imunoise.nav.state import I_DTH, I_Q, I_VEL, X_ATT, X_VEL

__all__ = ["GnssVelocity", "gnss_velocity", "as_gnss_velocity", "VEL_MAX_REJECT", "VEL_GATE_ABS"]

VEL_GATE_ABS = 0.1
"""Innovation floor of the velocity gate [m/s] (module docstring)."""
VEL_MAX_REJECT = 10
"""Consecutive rejected velocity fixes after which the next is forced in (module docstring; < 0: never)."""


class GnssVelocity(NamedTuple):
    """Velocity fixes of the GNSS antenna: times [s] (the IMU time base), NED velocity [m/s] (n, 3), 1σ NED
    [m/s] (n, 3)."""

    t: np.ndarray
    vel_ned: np.ndarray
    sigma_ned: np.ndarray
    gate_abs: float = VEL_GATE_ABS
    max_reject: int = VEL_MAX_REJECT
    dropped: int = 0


def as_gnss_velocity(t, vel_ned, sigma_ned, *, sigma_floor: float = 0.005, gate_abs: float = VEL_GATE_ABS,
                     max_reject: int = VEL_MAX_REJECT) -> GnssVelocity:
    """Checked, sorted fixes: rows with a non-finite time, velocity or σ are dropped (counted in ``dropped``);
    σ below ``sigma_floor`` (m/s) raised to it (a 0 σ would make the filter certain); a negative σ, or values
    that are not three columns North, East, Down, are refused (:class:`~imunoise.errors.DataError`).
    ``gate_abs``, ``max_reject``: the gate's guards (module docstring)."""
    t = np.asarray(t, dtype=float).ravel()
    v = np.asarray(vel_ned, dtype=float)
    if v.ndim > 2 or (v.ndim == 2 and v.shape[1] != 3) or (v.ndim < 2 and v.size % 3):
        raise DataError(f"GNSS velocity: values of shape {v.shape}; expected (n, 3) North, East, Down [m/s]")
    v = v.reshape(-1, 3)
    try:
        s = np.broadcast_to(np.asarray(sigma_ned, dtype=float), v.shape).copy()
    except ValueError as exc:
        raise DataError(f"GNSS velocity: σ of shape {np.shape(sigma_ned)} for {v.shape[0]} fixes; give one σ, "
                        "three (N, E, D) or one row per fix [m/s]") from exc
    if not (t.size == v.shape[0] == s.shape[0]):
        raise DataError(f"GNSS velocity: {t.size} times, {v.shape[0]} velocities and {s.shape[0]} σ rows differ")
    if np.any(s < 0):
        i = int(np.flatnonzero(np.any(s < 0, axis=1))[0])
        raise DataError(f"GNSS velocity: negative σ {s[i].tolist()} at fix {i} (t={t[i]:.3f}); σ is a standard "
                        "deviation [m/s], give it positive")
    ok = np.isfinite(t) & np.all(np.isfinite(v), axis=1) & np.all(np.isfinite(s), axis=1)
    order = np.argsort(t[ok], kind="stable")
    return GnssVelocity(np.ascontiguousarray(t[ok][order]), np.ascontiguousarray(v[ok][order]),
                        np.ascontiguousarray(np.maximum(s[ok][order], sigma_floor)), float(gate_abs), int(max_reject),
                        int(np.sum(~ok)))


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
