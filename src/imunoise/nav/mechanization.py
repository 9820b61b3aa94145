"""Increment-based strapdown mechanization in the local-level NED frame (docs/guide/theory.rst, 'Navigation filter').

Inputs are IMU increments Δθ_k, Δv_k over (t_{k−1}, t_k] in the body FRD frame. One step implements the
classical two-sample algorithm (Savage 1998; Shin 2001, Ch. 2; the same as KF-GINS ``INSMech``):

* velocity: Δv_f^b = Δv_k + ½ Δθ_k×Δv_k (rotation) + (Δθ_{k−1}×Δv_k + Δv_{k−1}×Δθ_k)/12 (sculling),
  projected with [I − ½ζ×] C_b^n(k−1), ζ = (ω_ie^n + ω_en^n) Δt; gravity/Coriolis
  [g^n − (2ω_ie^n + ω_en^n) × v^n] Δt at the mid-epoch (position and velocity extrapolated);
* position: trapezoidal velocity, radii at the mid-epoch height/latitude;
* attitude (quaternion q_b^n, Hamilton): q_k = q(−ζ) ⊗ q_{k−1} ⊗ q(φ_b), φ_b = Δθ_k + Δθ_{k−1}×Δθ_k/12
  (coning), ζ at the mid-epoch.

The navigation state is one float64 array ``nav`` of length :data:`NAV_LEN` so numba kernels can carry it:
``[lat, lon, h, vN, vE, vD, qw, qx, qy, qz, dθ_prev(3), dv_prev(3), prev_valid]``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from imunoise.nav.earth import OMEGA_E, dcm_to_euler, euler_to_dcm, gravity, radii
from imunoise.nav.state import I_DTH, I_DV, I_POS, I_PREV, I_Q, I_VEL, NAV_LEN

__all__ = [
    "NAV_LEN",
    "make_nav",
    "nav_llh",
    "nav_vel",
    "nav_dcm",
    "nav_euler",
    "quat_mul",
    "rotvec_to_quat",
    "quat_to_dcm",
    "dcm_to_quat",
    "strapdown_step",
    "integrate",
]


@njit(cache=True)
def quat_mul(p, q):
    """Hamilton product p ⊗ q of quaternions [w, x, y, z]."""
    return np.array(
        [
            p[0] * q[0] - p[1] * q[1] - p[2] * q[2] - p[3] * q[3],
            p[0] * q[1] + p[1] * q[0] + p[2] * q[3] - p[3] * q[2],
            p[0] * q[2] - p[1] * q[3] + p[2] * q[0] + p[3] * q[1],
            p[0] * q[3] + p[1] * q[2] - p[2] * q[1] + p[3] * q[0],
        ]
    )


@njit(cache=True)
def rotvec_to_quat(v):
    """Quaternion of the rotation vector v (rad): [cos(‖v‖/2), sin(‖v‖/2) v/‖v‖] (series near 0)."""
    a2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    if a2 < 1e-16:
        # Taylor series: exact to double precision below 1e-8 rad
        s = 0.5 - a2 / 48.0
        return np.array([1.0 - a2 / 8.0, s * v[0], s * v[1], s * v[2]])
    a = np.sqrt(a2)
    s = np.sin(0.5 * a) / a
    return np.array([np.cos(0.5 * a), s * v[0], s * v[1], s * v[2]])


@njit(cache=True)
def quat_to_dcm(q):
    """Rotation matrix of a unit quaternion (C_b^n for q_b^n)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    return np.array(
        [
            [w * w + x * x - y * y - z * z, 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
            [2.0 * (x * y + w * z), w * w - x * x + y * y - z * z, 2.0 * (y * z - w * x)],
            [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), w * w - x * x - y * y + z * z],
        ]
    )


@njit(cache=True)
def dcm_to_quat(C):
    """Unit quaternion (w ≥ 0) of a rotation matrix (Shepperd's method)."""
    tr = C[0, 0] + C[1, 1] + C[2, 2]
    q = np.empty(4)
    if tr > max(C[0, 0], C[1, 1], C[2, 2]):
        s = np.sqrt(1.0 + tr) * 2.0
        q[0] = 0.25 * s
        q[1] = (C[2, 1] - C[1, 2]) / s
        q[2] = (C[0, 2] - C[2, 0]) / s
        q[3] = (C[1, 0] - C[0, 1]) / s
    elif C[0, 0] >= C[1, 1] and C[0, 0] >= C[2, 2]:
        s = np.sqrt(1.0 + C[0, 0] - C[1, 1] - C[2, 2]) * 2.0
        q[0] = (C[2, 1] - C[1, 2]) / s
        q[1] = 0.25 * s
        q[2] = (C[0, 1] + C[1, 0]) / s
        q[3] = (C[0, 2] + C[2, 0]) / s
    elif C[1, 1] >= C[2, 2]:
        s = np.sqrt(1.0 + C[1, 1] - C[0, 0] - C[2, 2]) * 2.0
        q[0] = (C[0, 2] - C[2, 0]) / s
        q[1] = (C[0, 1] + C[1, 0]) / s
        q[2] = 0.25 * s
        q[3] = (C[1, 2] + C[2, 1]) / s
    else:
        s = np.sqrt(1.0 + C[2, 2] - C[0, 0] - C[1, 1]) * 2.0
        q[0] = (C[1, 0] - C[0, 1]) / s
        q[1] = (C[0, 2] + C[2, 0]) / s
        q[2] = (C[1, 2] + C[2, 1]) / s
        q[3] = 0.25 * s
    if q[0] < 0.0:
        q = -q
    return q / np.sqrt(np.sum(q * q))


def make_nav(llh: np.ndarray, vel_ned: np.ndarray, euler: np.ndarray) -> np.ndarray:
    """Navigation state array from position [lat rad, lon rad, h m], NED velocity and ZYX Euler angles."""
    nav = np.zeros(NAV_LEN)
    nav[I_POS : I_POS + 3] = np.asarray(llh, dtype=float)
    nav[I_VEL : I_VEL + 3] = np.asarray(vel_ned, dtype=float)
    e = np.asarray(euler, dtype=float)
    nav[I_Q : I_Q + 4] = dcm_to_quat(euler_to_dcm(e[0], e[1], e[2]))
    return nav


def nav_llh(nav: np.ndarray) -> np.ndarray:
    return nav[I_POS : I_POS + 3].copy()


def nav_vel(nav: np.ndarray) -> np.ndarray:
    return nav[I_VEL : I_VEL + 3].copy()


def nav_dcm(nav: np.ndarray) -> np.ndarray:
    return quat_to_dcm(nav[I_Q : I_Q + 4])


def nav_euler(nav: np.ndarray) -> np.ndarray:
    return dcm_to_euler(quat_to_dcm(nav[I_Q : I_Q + 4]))


@njit(cache=True)
def _rates(lat, h, vn, ve):
    """ω_ie^n + ω_en^n (the n-frame rate), 2ω_ie^n + ω_en^n (Coriolis), as two (3,) arrays."""
    rm, rn = radii(lat)
    sl, cl = np.sin(lat), np.cos(lat)
    wie = np.array([OMEGA_E * cl, 0.0, -OMEGA_E * sl])
    wen = np.array([ve / (rn + h), -vn / (rm + h), -ve * sl / cl / (rn + h)])
    return wie + wen, 2.0 * wie + wen


@njit(cache=True)
def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@njit(cache=True)
def strapdown_step(nav, dth, dv, dt):
    """Advance ``nav`` in place by one IMU increment (Δθ, Δv over dt); returns Δv_f^n (specific force, m/s).

    Two-sample coning/sculling with rotation compensation, Earth and transport rate, normal gravity
    (module docstring; Shin 2001 Eqs. 2.48-2.53).
    """
    if nav[I_PREV] == 0.0:
        # first step: no previous increment, assume the same motion before t_{k-1}
        for i in range(3):
            nav[I_DTH + i] = dth[i]
            nav[I_DV + i] = dv[i]
        nav[I_PREV] = 1.0
    dth_p = nav[I_DTH : I_DTH + 3].copy()
    dv_p = nav[I_DV : I_DV + 3].copy()
    lat, lon, h = nav[0], nav[1], nav[2]
    v0 = nav[I_VEL : I_VEL + 3].copy()
    q0 = nav[I_Q : I_Q + 4].copy()
    C0 = quat_to_dcm(q0)

    # --- velocity: specific-force increment with rotation + sculling compensation
    dvfb = dv + 0.5 * _cross(dth, dv) + (_cross(dth_p, dv) + _cross(dv_p, dth)) / 12.0
    win, wcor = _rates(lat, h, v0[0], v0[1])
    zeta = 0.5 * dt * win
    cvb = C0 @ dvfb
    dvfn = cvb - _cross(zeta, cvb)
    # mid-epoch extrapolation for gravity/Coriolis and the n-frame rotation
    g = gravity(lat, h)
    dvg = (np.array([0.0, 0.0, g]) - _cross(wcor, v0)) * dt
    vmid = v0 + 0.5 * (dvfn + dvg)
    rm, rn = radii(lat)
    hmid = h - 0.5 * vmid[2] * dt
    latmid = lat + 0.5 * vmid[0] * dt / (rm + hmid)
    win, wcor = _rates(latmid, hmid, vmid[0], vmid[1])
    zeta = 0.5 * dt * win
    dvfn = cvb - _cross(zeta, cvb)
    g = gravity(latmid, hmid)
    dvg = (np.array([0.0, 0.0, g]) - _cross(wcor, vmid)) * dt
    v1 = v0 + dvfn + dvg

    # --- position: trapezoidal velocity, radii at the mid epoch
    vm = 0.5 * (v0 + v1)
    h1 = h - vm[2] * dt
    hm = 0.5 * (h + h1)
    rm, rn = radii(lat)
    lat1 = lat + vm[0] * dt / (rm + hm)
    latm = 0.5 * (lat + lat1)
    rm, rn = radii(latm)
    lat1 = lat + vm[0] * dt / (rm + hm)
    latm = 0.5 * (lat + lat1)
    lon1 = lon + vm[1] * dt / ((rn + hm) * np.cos(latm))

    # --- attitude: body rotation with coning, n-frame rotation at the mid epoch
    win, wcor = _rates(latm, hm, vm[0], vm[1])
    phib = dth + _cross(dth_p, dth) / 12.0
    qbb = rotvec_to_quat(phib)
    qnn = rotvec_to_quat(-win * dt)
    q1 = quat_mul(quat_mul(qnn, q0), qbb)
    q1 = q1 / np.sqrt(np.sum(q1 * q1))

    nav[0], nav[1], nav[2] = lat1, lon1, h1
    for i in range(3):
        nav[I_VEL + i] = v1[i]
        nav[I_DTH + i] = dth[i]
        nav[I_DV + i] = dv[i]
    for i in range(4):
        nav[I_Q + i] = q1[i]
    return dvfn


@njit(cache=True)
def _integrate(nav, t, dtheta, dv, out_llh, out_vel, out_euler):
    n = t.shape[0]
    for k in range(1, n):
        dt = t[k] - t[k - 1]
        strapdown_step(nav, dtheta[k], dv[k], dt)
        for i in range(3):
            out_llh[k, i] = nav[I_POS + i]
            out_vel[k, i] = nav[I_VEL + i]
        out_euler[k] = dcm_to_euler(quat_to_dcm(nav[I_Q : I_Q + 4]))


def integrate(
    t: np.ndarray,
    dtheta: np.ndarray,
    dv: np.ndarray,
    llh0: np.ndarray,
    vel0: np.ndarray,
    euler0: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pure inertial navigation from the state at ``t[0]`` through all increments (rows 1..n−1).

    Returns (llh (n,3), vel_ned (n,3), euler (n,3)); row 0 is the initial state. Row k uses the
    increment of row k over (t[k−1], t[k]]; the increment of row 0 only seeds the coning/sculling memory.
    """
    t = np.ascontiguousarray(t, dtype=float)
    dtheta = np.ascontiguousarray(dtheta, dtype=float)
    dv = np.ascontiguousarray(dv, dtype=float)
    nav = make_nav(llh0, vel0, euler0)
    nav[I_DTH : I_DTH + 3] = dtheta[0]
    nav[I_DV : I_DV + 3] = dv[0]
    nav[I_PREV] = 1.0
    n = t.shape[0]
    out_llh = np.empty((n, 3))
    out_vel = np.empty((n, 3))
    out_euler = np.empty((n, 3))
    out_llh[0], out_vel[0], out_euler[0] = llh0, vel0, euler0
    _integrate(nav, t, dtheta, dv, out_llh, out_vel, out_euler)
    return out_llh, out_vel, out_euler
