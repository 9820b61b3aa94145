"""WGS84 Earth model: radii, normal gravity, Earth and transport rates, LLH/ECEF/NED, Euler/DCM
(docs/guide/theory.rst, 'Navigation filter').

Conventions (docs/guide/theory.rst, 'Conventions'): geodetic ``llh = [lat rad, lon rad, h m]``; navigation frame
local-level NED; attitude ``C_b^n`` with ZYX Euler angles (roll, pitch, yaw) only at I/O.

The scalar functions are ``numba.njit`` dispatchers: callable from Python and from other numba kernels
(the strapdown hot loop uses them directly). ``radii`` and ``gravity`` use ``np.*`` math so they also
accept arrays of latitudes/heights.
"""

from __future__ import annotations

import numpy as np
from numba import njit

A = 6378137.0  # semi-major axis, m
F = 1.0 / 298.257223563  # flattening
E2 = F * (2.0 - F)  # first eccentricity squared
B = A * (1.0 - F)  # semi-minor axis, m
EP2 = (A * A - B * B) / (B * B)  # second eccentricity squared
OMEGA_E = 7.2921151467e-5  # Earth rotation rate, rad/s
GM = 3.986004418e14  # gravitational constant times Earth mass, m^3/s^2

__all__ = [
    "A",
    "F",
    "E2",
    "OMEGA_E",
    "GM",
    "radii",
    "gravity",
    "omega_ie_n",
    "omega_en_n",
    "llh_to_ecef",
    "ecef_to_llh",
    "ecef_to_ned_matrix",
    "llh_to_ned",
    "ned_to_llh",
    "euler_to_dcm",
    "dcm_to_euler",
    "skew",
]


@njit(cache=True)
def radii(lat):
    """Meridian and prime-vertical radii of curvature (R_M, R_N) in m at geodetic latitude ``lat`` (rad).

    R_N = a / sqrt(1 - e² sin²φ), R_M = R_N (1 - e²) / (1 - e² sin²φ)  (Groves 2013, Eqs. 2.105-2.106).
    """
    s = np.sin(lat)
    w = 1.0 - E2 * s * s
    rn = A / np.sqrt(w)
    rm = rn * (1.0 - E2) / w
    return rm, rn


@njit(cache=True)
def gravity(lat, h):
    """Normal gravity magnitude (m/s², positive down in NED) at latitude ``lat`` (rad) and height ``h`` (m).

    Somigliana closed form on the ellipsoid (series coefficients of WGS84) with the second-order free-air
    height correction; the same formula as KF-GINS (``Earth::gravity``) so results compare like for like.
    """
    s2 = np.sin(lat) ** 2
    g0 = 9.7803267715 * (1.0 + 0.0052790414 * s2 + 0.0000232718 * s2 * s2)
    return g0 - (3.087691089e-6 - 4.397731e-9 * s2) * h + 0.721e-12 * h * h


@njit(cache=True)
def omega_ie_n(lat):
    """Earth rotation rate ω_ie^n in NED (rad/s): Ω·[cos φ, 0, −sin φ]."""
    return np.array([OMEGA_E * np.cos(lat), 0.0, -OMEGA_E * np.sin(lat)])


@njit(cache=True)
def omega_en_n(lat, h, v_ned):
    """Transport rate ω_en^n in NED (rad/s): [v_E/(R_N+h), −v_N/(R_M+h), −v_E tan φ/(R_N+h)]."""
    rm, rn = radii(lat)
    return np.array(
        [
            v_ned[1] / (rn + h),
            -v_ned[0] / (rm + h),
            -v_ned[1] * np.tan(lat) / (rn + h),
        ]
    )


@njit(cache=True)
def skew(v):
    """Skew-symmetric (cross-product) matrix [v×]."""
    return np.array(
        [
            [0.0, -v[2], v[1]],
            [v[2], 0.0, -v[0]],
            [-v[1], v[0], 0.0],
        ]
    )


@njit(cache=True)
def ecef_to_ned_matrix(lat, lon):
    """Rotation C_e^n from ECEF to the local NED frame at (lat, lon) in rad."""
    sl, cl = np.sin(lat), np.cos(lat)
    so, co = np.sin(lon), np.cos(lon)
    return np.array(
        [
            [-sl * co, -sl * so, cl],
            [-so, co, 0.0],
            [-cl * co, -cl * so, -sl],
        ]
    )


@njit(cache=True)
def euler_to_dcm(roll, pitch, yaw):
    """C_b^n from ZYX Euler angles (rad): C = R_z(yaw) R_y(pitch) R_x(roll)."""
    sr, cr = np.sin(roll), np.cos(roll)
    sp, cp = np.sin(pitch), np.cos(pitch)
    sy, cy = np.sin(yaw), np.cos(yaw)
    return np.array(
        [
            [cp * cy, -cr * sy + sr * sp * cy, sr * sy + cr * sp * cy],
            [cp * sy, cr * cy + sr * sp * sy, -sr * cy + cr * sp * sy],
            [-sp, sr * cp, cr * cp],
        ]
    )


@njit(cache=True)
def dcm_to_euler(C_bn):
    """ZYX Euler angles [roll, pitch, yaw] (rad) of C_b^n; yaw in (−π, π]."""
    roll = np.arctan2(C_bn[2, 1], C_bn[2, 2])
    pitch = np.arctan2(-C_bn[2, 0], np.sqrt(C_bn[2, 1] ** 2 + C_bn[2, 2] ** 2))
    yaw = np.arctan2(C_bn[1, 0], C_bn[0, 0])
    return np.array([roll, pitch, yaw])


def llh_to_ecef(llh: np.ndarray) -> np.ndarray:
    """Geodetic [lat rad, lon rad, h m] → ECEF [x, y, z] m; works on one point (3,) or rows (n, 3)."""
    llh = np.asarray(llh, dtype=float)
    lat, lon, h = llh[..., 0], llh[..., 1], llh[..., 2]
    _, rn = radii(lat)
    cl = np.cos(lat)
    x = (rn + h) * cl * np.cos(lon)
    y = (rn + h) * cl * np.sin(lon)
    z = (rn * (1.0 - E2) + h) * np.sin(lat)
    return np.stack([x, y, z], axis=-1)


def ecef_to_llh(xyz: np.ndarray) -> np.ndarray:
    """ECEF [x, y, z] m → geodetic [lat rad, lon rad, h m]; one point (3,) or rows (n, 3).

    Heikkinen's exact closed form (Zhu 1994), sub-millimetre everywhere except at the Earth's centre.
    """
    xyz = np.asarray(xyz, dtype=float)
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    p = np.hypot(x, y)
    z2 = z * z
    ff = 54.0 * B * B * z2
    g = p * p + (1.0 - E2) * z2 - E2 * (A * A - B * B)
    c = E2 * E2 * ff * p * p / (g**3)
    s = np.cbrt(1.0 + c + np.sqrt(c * c + 2.0 * c))
    k = s + 1.0 + 1.0 / s
    pp = ff / (3.0 * k * k * g * g)
    q = np.sqrt(1.0 + 2.0 * E2 * E2 * pp)
    rad = 0.5 * A * A * (1.0 + 1.0 / q) - pp * (1.0 - E2) * z2 / (q * (1.0 + q)) - 0.5 * pp * p * p
    r0 = -(pp * E2 * p) / (1.0 + q) + np.sqrt(np.maximum(rad, 0.0))
    u = np.sqrt((p - E2 * r0) ** 2 + z2)
    v = np.sqrt((p - E2 * r0) ** 2 + (1.0 - E2) * z2)
    z0 = B * B * z / (A * v)
    h = u * (1.0 - B * B / (A * v))
    lat = np.arctan((z + EP2 * z0) / p)
    lon = np.arctan2(y, x)
    return np.stack([lat, lon, h], axis=-1)


def llh_to_ned(llh: np.ndarray, llh0: np.ndarray) -> np.ndarray:
    """Local NED offsets (m) of points ``llh`` relative to ``llh0``, exact via ECEF: C_e^n(x − x0)."""
    llh0 = np.asarray(llh0, dtype=float)
    d = llh_to_ecef(llh) - llh_to_ecef(llh0)
    return d @ ecef_to_ned_matrix(llh0[0], llh0[1]).T


def ned_to_llh(ned: np.ndarray, llh0: np.ndarray) -> np.ndarray:
    """Inverse of :func:`llh_to_ned`: geodetic coordinates of NED offsets ``ned`` (m) from ``llh0``."""
    llh0 = np.asarray(llh0, dtype=float)
    xyz = llh_to_ecef(llh0) + np.asarray(ned, dtype=float) @ ecef_to_ned_matrix(llh0[0], llh0[1])
    return ecef_to_llh(xyz)
