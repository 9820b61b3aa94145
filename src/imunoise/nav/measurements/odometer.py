"""Wheel odometer (vehicle speed): the forward speed of the vehicle in its own frame (Shin 2001 §5.2; KF-GINS'
odometer/NHC branch), from wheel encoders, a CAN vehicle-speed message or a ``Twist``'s ``linear.x``.

The wheel point (lever arm l from the IMU, body FRD, m; the rear axle's centre for a car) moves with
v^b + ω × l, v^b = C_b^nᵀ v^n. With the error conventions of :mod:`imunoise.nav.ekf` (Ĉ = (I − φ×)C,
δv = v̂ − v) and c the forward axis of the body in the navigation frame (column x of C_b^n):

    ŝ = cᵀ v̂^n + (ω̂ × l)_x,     dz = ŝ − z,     H = [0, cᵀ, (v̂^n × c)ᵀ, 0]

the attitude row being the forward row of −C_b^nᵀ(v̂^n×) as in :mod:`.nhc` (ω̂ is the last corrected increment
Δθ̂/Δt; the gyro-bias coupling of the lever term, |l|·δb < 1e-6 m/s, is left out).

The scale factor. The odometer reads z = (1 + ε) s + n for the true speed s: the wheel radius is known to
about a percent (tyre pressure, wear, load). ε is a random constant of one drive; as a filter state it would
need its own column in the error-state layout (:mod:`imunoise.nav.error_states`) and its propagation. Here it
enters the measurement noise instead, with its 1σ ``sf_sigma`` (default :data:`ODO_SF_SIGMA` = 1 %):

    R = σ_v² + (sf_sigma · ŝ)²

which treats a constant error as white and so is optimistic over long outages (a 1 % error accumulates 1 % of
the distance driven along the track: 9 m over 60 s at 15 m/s, against the tens to hundreds of metres of an
unaided MEMS IMU); a known scale factor (a calibration) is divided out by the reader. Each epoch's 1σ row is
``(σ_v, sf_sigma)``.

The gate: the χ² gate of :func:`~imunoise.nav.ekf_kernels.kf_update` (1 dof) with the guards of the GNSS
velocity gate (:mod:`.gnss_velocity`): innovations below ``gate_abs`` (default :data:`ODO_GATE_ABS` =
0.1 m/s) are never outliers and after ``max_reject`` (default :data:`ODO_MAX_REJECT`) consecutive rejections
the next epoch is forced in, since in an outage the filter's velocity error outgrows its covariance exactly
when the odometer is the aiding that matters. Speeds are unsigned (a wheel-speed sensor does not see reverse):
the filter's forward speed is compared as it is, so reversing manoeuvres must be left out of the file.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from imunoise.nav.mechanization import quat_to_dcm
from imunoise.nav.state import I_DTH, I_Q, I_VEL, X_ATT, X_VEL

__all__ = ["odometer", "forward_speed", "ODO_SIGMA", "ODO_SF_SIGMA", "ODO_GATE_ABS", "ODO_MAX_REJECT"]

ODO_SIGMA = 0.05
"""Default white-noise 1σ of an odometer speed [m/s] (encoder quantisation, CAN resolution)."""
ODO_SF_SIGMA = 0.01
"""Default 1σ of the odometer's relative scale-factor error (1 %; module docstring)."""
ODO_GATE_ABS = 0.1
"""Innovation floor of the odometer gate [m/s] (module docstring)."""
ODO_MAX_REJECT = 10
"""Consecutive rejected odometer epochs after which the next is forced in (module docstring)."""


@njit(cache=True)
def odometer(nav, n, z, lever, dt, sigma):
    """(dz (1,), H (1, n), R (1, 1)) of a forward speed ``z[0]`` [m/s] at the wheel point ``lever`` (body FRD,
    m) with 1σ row ``sigma`` = (σ_v [m/s], relative scale-factor σ); ``dt`` is the interval of the last increment
    (for ω̂)."""
    C = quat_to_dcm(nav[I_Q : I_Q + 4])
    c0, c1, c2 = C[0, 0], C[1, 0], C[2, 0]  # body x in the navigation frame
    vn, ve, vd = nav[I_VEL], nav[I_VEL + 1], nav[I_VEL + 2]
    wy = nav[I_DTH + 1] / dt if dt > 0.0 else 0.0
    wz = nav[I_DTH + 2] / dt if dt > 0.0 else 0.0
    s = c0 * vn + c1 * ve + c2 * vd + wy * lever[2] - wz * lever[1]
    dz = np.empty(1)
    dz[0] = s - z[0]
    H = np.zeros((1, n))
    H[0, X_VEL], H[0, X_VEL + 1], H[0, X_VEL + 2] = c0, c1, c2
    H[0, X_ATT] = ve * c2 - vd * c1  # (v × c)ᵀ = −cᵀ(v×)
    H[0, X_ATT + 1] = vd * c0 - vn * c2
    H[0, X_ATT + 2] = vn * c1 - ve * c0
    R = np.zeros((1, 1))
    R[0, 0] = sigma[0] * sigma[0] + (sigma[1] * s) ** 2
    return dz, H, R


def forward_speed(vel_ned: np.ndarray, euler: np.ndarray) -> np.ndarray:
    """The body-x speed cᵀ v^n [m/s] of NED velocities (n, 3) at attitudes (roll, pitch, yaw; rad) (n, 3): what an
    odometer at the IMU reads without errors (the simulator's truth)."""
    e = np.asarray(euler, dtype=float)
    p, y = e[:, 1], e[:, 2]
    c = np.column_stack([np.cos(p) * np.cos(y), np.cos(p) * np.sin(y), -np.sin(p)])  # column x of C_b^n
    return np.sum(c * np.asarray(vel_ned, dtype=float), axis=1)
