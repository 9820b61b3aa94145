"""GNSS antenna position (docs/guide/theory.rst, 'Navigation filter'; KF-GINS ``GNSSUpdate``).

dz = D_R (r̂ + D_R⁻¹ C_b^n l − r_gnss) − v̂·δt (NED m) for a fix δt before the filter epoch, with the lever arm
l (body FRD, m); H = [I, 0, (C_b^n l)×, 0]; R = diag(σ²). The velocity term refers the fix to the filter epoch
(exact to ½·a·δt² < 1 mm at 100 Hz).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from imunoise.nav.earth import radii
from imunoise.nav.mechanization import quat_to_dcm
from imunoise.nav.state import I_Q, I_VEL, X_ATT, X_POS

__all__ = ["gnss_position"]


@njit(cache=True)
def gnss_position(nav, n, z_llh, lever, dt_back, sigma):
    """(dz (3,), H (3, n), R (3, 3)) of a fix ``z_llh`` (rad, rad, m) with 1σ NED ``sigma`` (m)."""
    lat, h = nav[0], nav[2]
    rm, rn = radii(lat)
    C = quat_to_dcm(nav[I_Q : I_Q + 4])
    lC = np.zeros(3)  # C_b^n l
    for i in range(3):
        for j in range(3):
            lC[i] += C[i, j] * lever[j]
    dz = np.empty(3)
    dz[0] = (lat - z_llh[0]) * (rm + h) + lC[0] - nav[I_VEL] * dt_back
    dz[1] = (nav[1] - z_llh[1]) * (rn + h) * math.cos(lat) + lC[1] - nav[I_VEL + 1] * dt_back
    dz[2] = -(h - z_llh[2]) + lC[2] - nav[I_VEL + 2] * dt_back
    H = np.zeros((3, n))
    for i in range(3):
        H[i, X_POS + i] = 1.0
    H[0, X_ATT + 1] = -lC[2]
    H[0, X_ATT + 2] = lC[1]
    H[1, X_ATT] = lC[2]
    H[1, X_ATT + 2] = -lC[0]
    H[2, X_ATT] = -lC[1]
    H[2, X_ATT + 1] = lC[0]
    R = np.zeros((3, 3))
    for i in range(3):
        R[i, i] = sigma[i] * sigma[i]
    return dz, H, R
