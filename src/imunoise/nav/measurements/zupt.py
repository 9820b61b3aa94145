"""Zero-velocity (ZUPT) and zero-angular-rate (ZARU) updates at stops (docs/guide/theory.rst, 'Static detection'–8).

ZUPT: dz = v̂^n, H = [0, I, 0, 0], R = σ_v² I. ZARU: the last corrected angular rate equals the Earth rate in
body, dz = Δθ̂/Δt − C_b^nᵀ ω_ie^n, H couples the gyro model states (H[a, 9 + s] = h_s for the states of gyro
axis a), R = σ_w² I.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from imunoise.nav.earth import OMEGA_E
from imunoise.nav.mechanization import quat_to_dcm
from imunoise.nav.state import I_DTH, I_Q, I_VEL, X_MODEL, X_VEL

__all__ = ["zupt", "zaru"]


@njit(cache=True)
def zupt(nav, n, sigma_v):
    """(dz, H, R) of v^n = 0 with 1σ ``sigma_v`` (m/s)."""
    H = np.zeros((3, n))
    R = np.zeros((3, 3))
    dz = np.empty(3)
    for i in range(3):
        H[i, X_VEL + i] = 1.0
        R[i, i] = sigma_v * sigma_v
        dz[i] = nav[I_VEL + i]
    return dz, H, R


@njit(cache=True)
def zaru(nav, n, dt, hvec, axis_of, sigma_w):
    """(dz, H, R) of ω_ib^b = C_b^nᵀ ω_ie^n from the last corrected increment over ``dt`` (s), 1σ ``sigma_w``
    (rad/s); ``hvec``/``axis_of``: the model layout (:class:`~imunoise.nav.error_states.ModelLayout`)."""
    C = quat_to_dcm(nav[I_Q : I_Q + 4])
    lat = nav[0]
    wn = np.array([OMEGA_E * math.cos(lat), 0.0, -OMEGA_E * math.sin(lat)])
    dz = np.empty(3)
    for i in range(3):
        dz[i] = nav[I_DTH + i] / dt - (C[0, i] * wn[0] + C[1, i] * wn[1] + C[2, i] * wn[2])
    H = np.zeros((3, n))
    for s in range(hvec.shape[0]):
        if axis_of[s] < 3:
            H[axis_of[s], X_MODEL + s] = hvec[s]
    R = np.zeros((3, 3))
    for i in range(3):
        R[i, i] = sigma_w * sigma_w
    return dz, H, R
