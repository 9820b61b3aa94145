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
    "quat_mul4",
    "rotvec_to_quat",
    "rotvec_quat4",
    "quat_to_dcm",
    "dcm9",
    "quat_euler",
    "dcm_to_quat",
    "strapdown",
    "strapdown_step",
    "integrate",
]


@njit(cache=True)
def quat_mul4(p0, p1, p2, p3, q0, q1, q2, q3):
    """Hamilton product p ⊗ q of quaternions given as scalars [w, x, y, z]; four scalars (no array: the
    strapdown calls it every sample)."""
    return (p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3,
            p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2,
            p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1,
            p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0)


@njit(cache=True)
def quat_mul(p, q):
    """Hamilton product p ⊗ q of quaternions [w, x, y, z]."""
    w, x, y, z = quat_mul4(p[0], p[1], p[2], p[3], q[0], q[1], q[2], q[3])
    return np.array([w, x, y, z])


@njit(cache=True)
def rotvec_quat4(v0, v1, v2):
    """Quaternion of the rotation vector (v0, v1, v2) (rad) as four scalars: [cos(‖v‖/2), sin(‖v‖/2) v/‖v‖]
    (series near 0)."""
    a2 = v0 * v0 + v1 * v1 + v2 * v2
    if a2 < 1e-16:
        # Taylor series: exact to double precision below 1e-8 rad
        s = 0.5 - a2 / 48.0
        return 1.0 - a2 / 8.0, s * v0, s * v1, s * v2
    a = np.sqrt(a2)
    s = np.sin(0.5 * a) / a
    return np.cos(0.5 * a), s * v0, s * v1, s * v2


@njit(cache=True)
def rotvec_to_quat(v):
    """Quaternion of the rotation vector v (rad): [cos(‖v‖/2), sin(‖v‖/2) v/‖v‖] (series near 0)."""
    w, x, y, z = rotvec_quat4(v[0], v[1], v[2])
    return np.array([w, x, y, z])


@njit(cache=True)
def dcm9(w, x, y, z):
    """Rotation matrix of the unit quaternion (w, x, y, z) as nine scalars, row by row (C_b^n for q_b^n)."""
    return (w * w + x * x - y * y - z * z, 2.0 * (x * y - w * z), 2.0 * (x * z + w * y),
            2.0 * (x * y + w * z), w * w - x * x + y * y - z * z, 2.0 * (y * z - w * x),
            2.0 * (x * z - w * y), 2.0 * (y * z + w * x), w * w - x * x - y * y + z * z)


@njit(cache=True)
def quat_to_dcm(q):
    """Rotation matrix of a unit quaternion (C_b^n for q_b^n)."""
    c = dcm9(q[0], q[1], q[2], q[3])
    C = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            C[i, j] = c[3 * i + j]
    return C


@njit(cache=True)
def quat_euler(w, x, y, z):
    """ZYX Euler angles (roll, pitch, yaw; rad) of the unit quaternion (w, x, y, z): the arithmetic of
    ``dcm_to_euler(quat_to_dcm(q))`` without its two arrays."""
    c = dcm9(w, x, y, z)
    roll = np.arctan2(c[7], c[8])
    pitch = np.arctan2(-c[6], np.sqrt(c[7] ** 2 + c[8] ** 2))
    yaw = np.arctan2(c[3], c[0])
    return roll, pitch, yaw


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
    """ω_ie^n + ω_en^n (the n-frame rate) and 2ω_ie^n + ω_en^n (Coriolis), as six scalars (x, y, z of each)."""
    rm, rn = radii(lat)
    sl, cl = np.sin(lat), np.cos(lat)
    ie0, ie1, ie2 = OMEGA_E * cl, 0.0, -OMEGA_E * sl
    en0, en1, en2 = ve / (rn + h), -vn / (rm + h), -ve * sl / cl / (rn + h)
    return ie0 + en0, ie1 + en1, ie2 + en2, 2.0 * ie0 + en0, 2.0 * ie1 + en1, 2.0 * ie2 + en2


@njit(cache=True)
def _cross(a0, a1, a2, b0, b1, b2):
    """a × b of two vectors given as scalars."""
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(cache=True)
def strapdown(nav, t0, t1, t2, u0, u1, u2, dt):
    """Advance ``nav`` in place by one IMU increment Δθ = (t0, t1, t2), Δv = (u0, u1, u2) over dt; returns
    Δv_f^n (specific force, m/s) as three scalars.

    Two-sample coning/sculling with rotation compensation, Earth and transport rate, normal gravity
    (module docstring; Shin 2001 Eqs. 2.48-2.53). Written on scalars, every vector operation in the order of
    its array form (bit for bit): the filter runs it every sample, and small arrays cost more to allocate
    than to compute with. The body-to-n projection stays a matrix product (BLAS, as before).
    """
    if nav[I_PREV] == 0.0:
        # first step: no previous increment, assume the same motion before t_{k-1}
        nav[I_DTH], nav[I_DTH + 1], nav[I_DTH + 2] = t0, t1, t2
        nav[I_DV], nav[I_DV + 1], nav[I_DV + 2] = u0, u1, u2
        nav[I_PREV] = 1.0
    p0, p1, p2 = nav[I_DTH], nav[I_DTH + 1], nav[I_DTH + 2]
    r0, r1, r2 = nav[I_DV], nav[I_DV + 1], nav[I_DV + 2]
    lat, lon, h = nav[0], nav[1], nav[2]
    vn, ve, vd = nav[I_VEL], nav[I_VEL + 1], nav[I_VEL + 2]
    qw, qx, qy, qz = nav[I_Q], nav[I_Q + 1], nav[I_Q + 2], nav[I_Q + 3]
    C0 = quat_to_dcm(nav[I_Q : I_Q + 4])

    # --- velocity: specific-force increment with rotation + sculling compensation
    a0, a1, a2 = _cross(t0, t1, t2, u0, u1, u2)
    b0, b1, b2 = _cross(p0, p1, p2, u0, u1, u2)
    c0, c1, c2 = _cross(r0, r1, r2, t0, t1, t2)
    dvfb = np.empty(3)
    dvfb[0] = u0 + 0.5 * a0 + (b0 + c0) / 12.0
    dvfb[1] = u1 + 0.5 * a1 + (b1 + c1) / 12.0
    dvfb[2] = u2 + 0.5 * a2 + (b2 + c2) / 12.0
    cvb = C0 @ dvfb
    w0, w1, w2, k0, k1, k2 = _rates(lat, h, vn, ve)
    x0, x1, x2 = _cross(0.5 * dt * w0, 0.5 * dt * w1, 0.5 * dt * w2, cvb[0], cvb[1], cvb[2])
    f0, f1, f2 = cvb[0] - x0, cvb[1] - x1, cvb[2] - x2
    # mid-epoch extrapolation for gravity/Coriolis and the n-frame rotation
    g = gravity(lat, h)
    y0, y1, y2 = _cross(k0, k1, k2, vn, ve, vd)
    g0, g1, g2 = (0.0 - y0) * dt, (0.0 - y1) * dt, (g - y2) * dt
    m0, m1, m2 = vn + 0.5 * (f0 + g0), ve + 0.5 * (f1 + g1), vd + 0.5 * (f2 + g2)
    rm, rn = radii(lat)
    hmid = h - 0.5 * m2 * dt
    latmid = lat + 0.5 * m0 * dt / (rm + hmid)
    w0, w1, w2, k0, k1, k2 = _rates(latmid, hmid, m0, m1)
    x0, x1, x2 = _cross(0.5 * dt * w0, 0.5 * dt * w1, 0.5 * dt * w2, cvb[0], cvb[1], cvb[2])
    f0, f1, f2 = cvb[0] - x0, cvb[1] - x1, cvb[2] - x2
    g = gravity(latmid, hmid)
    y0, y1, y2 = _cross(k0, k1, k2, m0, m1, m2)
    g0, g1, g2 = (0.0 - y0) * dt, (0.0 - y1) * dt, (g - y2) * dt
    v1n, v1e, v1d = vn + f0 + g0, ve + f1 + g1, vd + f2 + g2

    # --- position: trapezoidal velocity, radii at the mid epoch
    mn, me, md = 0.5 * (vn + v1n), 0.5 * (ve + v1e), 0.5 * (vd + v1d)
    h1 = h - md * dt
    hm = 0.5 * (h + h1)
    rm, rn = radii(lat)
    lat1 = lat + mn * dt / (rm + hm)
    latm = 0.5 * (lat + lat1)
    rm, rn = radii(latm)
    lat1 = lat + mn * dt / (rm + hm)
    latm = 0.5 * (lat + lat1)
    lon1 = lon + me * dt / ((rn + hm) * np.cos(latm))

    # --- attitude: body rotation with coning, n-frame rotation at the mid epoch
    w0, w1, w2, k0, k1, k2 = _rates(latm, hm, mn, me)
    e0, e1, e2 = _cross(p0, p1, p2, t0, t1, t2)
    bw, bx, by, bz = rotvec_quat4(t0 + e0 / 12.0, t1 + e1 / 12.0, t2 + e2 / 12.0)
    nw, nx, ny, nz = rotvec_quat4(-w0 * dt, -w1 * dt, -w2 * dt)
    sw, sx, sy, sz = quat_mul4(nw, nx, ny, nz, qw, qx, qy, qz)
    sw, sx, sy, sz = quat_mul4(sw, sx, sy, sz, bw, bx, by, bz)
    norm = np.sqrt(sw * sw + sx * sx + sy * sy + sz * sz)

    nav[0], nav[1], nav[2] = lat1, lon1, h1
    nav[I_VEL], nav[I_VEL + 1], nav[I_VEL + 2] = v1n, v1e, v1d
    nav[I_DTH], nav[I_DTH + 1], nav[I_DTH + 2] = t0, t1, t2
    nav[I_DV], nav[I_DV + 1], nav[I_DV + 2] = u0, u1, u2
    nav[I_Q], nav[I_Q + 1], nav[I_Q + 2], nav[I_Q + 3] = sw / norm, sx / norm, sy / norm, sz / norm
    return f0, f1, f2


@njit(cache=True)
def strapdown_step(nav, dth, dv, dt):
    """Advance ``nav`` in place by one IMU increment (Δθ, Δv over dt); returns Δv_f^n (specific force, m/s)
    (:func:`strapdown` on arrays)."""
    f0, f1, f2 = strapdown(nav, dth[0], dth[1], dth[2], dv[0], dv[1], dv[2], dt)
    return np.array([f0, f1, f2])


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
