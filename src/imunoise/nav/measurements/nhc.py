"""Non-holonomic constraints (NHC): a car does not slide sideways nor leave the road (Shin 2001 §5.2; KF-GINS'
odometer/NHC branch), so its body-frame velocity has zero lateral and vertical components while it rolls.

With v^b = C_b^nᵀ v^n and the error conventions of :mod:`imunoise.nav.ekf` (Ĉ = (I − φ×)C, δv = v̂ − v):

    v̂^b ≈ v^b + C_b^nᵀ δv − C_b^nᵀ (v̂^n×) φ,     dz = [v̂^b_y, v̂^b_z],   H = rows y, z of [0, C_b^nᵀ, −C_b^nᵀ(v̂^n×), 0]

R = diag(σ_lat², σ_vert²). The constraint holds at the rear axle; at the IMU it breaks in turns (ω_z × lever)
and in skids, hence the gate (:func:`nhc_gate`): applied only above ``min_speed`` (below it ZUPT's stops and
creeping manoeuvres), with the last corrected yaw rate |ω_z| ≤ ``max_yaw_rate`` and lateral specific force
|f_y| ≤ ``max_lat_acc``, and through the χ² gate of :func:`~imunoise.nav.ekf_kernels.kf_update` (2 dof),
which accepts the constraint anyway after ``max_reject`` consecutive rejections (as the GNSS gate does): in a
GNSS outage the filter's velocity drifts, the NIS grows with it, and a plain χ² gate would shut the constraint
out exactly when it is needed (measured on drive_0708, five 60 s outages: 181 m mean drift with the gate
alone, 33 m without any χ² gate).
Every ``every`` IMU samples (10 Hz at 100 Hz by default): the constraint's error (mounting misalignment, road
camber) is correlated in time, so more frequent updates add confidence, not information.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from imunoise.errors import ModelError
from imunoise.nav.mechanization import quat_to_dcm
from imunoise.nav.state import I_DTH, I_DV, I_Q, I_VEL, X_ATT, X_VEL

__all__ = ["NhcConfig", "NhcSettings", "nhc", "nhc_gate", "NHC_OFF"]


class NhcSettings(NamedTuple):
    """The kernel's form of :class:`NhcConfig` (``every`` = 0: off)."""

    every: int
    sigma_lat: float
    sigma_vert: float
    min_speed: float
    max_yaw_rate: float
    max_lat_acc: float
    chi2: float
    max_reject: int


NHC_OFF = NhcSettings(0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0)


@dataclass(frozen=True)
class NhcConfig:
    """NHC settings (module docstring): σ of the lateral and vertical body velocity [m/s], one update every
    ``every`` IMU samples, gate: horizontal speed ≥ ``min_speed`` [m/s], |yaw rate| ≤ ``max_yaw_rate``
    [rad/s], |lateral specific force| ≤ ``max_lat_acc`` [m/s²], NIS ≤ ``chi2`` (2 dof; 13.8 = 99.9 %; 0 = no
    χ² gate) unless ``max_reject`` updates in a row were rejected."""

    sigma_lat: float = 0.1
    sigma_vert: float = 0.1
    every: int = 10
    min_speed: float = 3.0
    max_yaw_rate: float = 0.3
    max_lat_acc: float = 3.0
    chi2: float = 13.8
    max_reject: int = 10

    def __post_init__(self) -> None:
        if not (self.sigma_lat > 0 and self.sigma_vert > 0 and self.every >= 1):
            raise ModelError("NhcConfig: sigma_lat and sigma_vert must be > 0 m/s and every ≥ 1 sample")
        if not (self.min_speed >= 0 and self.max_yaw_rate > 0 and self.max_lat_acc > 0 and self.chi2 >= 0
                and self.max_reject >= 0):
            raise ModelError("NhcConfig: min_speed ≥ 0, max_yaw_rate > 0, max_lat_acc > 0, chi2 ≥ 0 (0 = no gate) "
                             "and max_reject ≥ 0")

    def kernel(self) -> NhcSettings:
        return NhcSettings(int(self.every), float(self.sigma_lat), float(self.sigma_vert), float(self.min_speed),
                           float(self.max_yaw_rate), float(self.max_lat_acc), float(self.chi2), int(self.max_reject))


@njit(cache=True)
def nhc(nav, n, sigma_lat, sigma_vert):
    """(dz (2,), H (2, n), R (2, 2)) of v^b_y = v^b_z = 0."""
    C = quat_to_dcm(nav[I_Q : I_Q + 4])
    vn, ve, vd = nav[I_VEL], nav[I_VEL + 1], nav[I_VEL + 2]
    dz = np.empty(2)
    H = np.zeros((2, n))
    for r in range(2):
        b = r + 1  # body y, z
        c0, c1, c2 = C[0, b], C[1, b], C[2, b]  # row b of C_b^nᵀ
        dz[r] = c0 * vn + c1 * ve + c2 * vd
        H[r, X_VEL], H[r, X_VEL + 1], H[r, X_VEL + 2] = c0, c1, c2
        # −cᵀ(v×) = (v × c)ᵀ
        H[r, X_ATT] = ve * c2 - vd * c1
        H[r, X_ATT + 1] = vd * c0 - vn * c2
        H[r, X_ATT + 2] = vn * c1 - ve * c0
    R = np.zeros((2, 2))
    R[0, 0] = sigma_lat * sigma_lat
    R[1, 1] = sigma_vert * sigma_vert
    return dz, H, R


@njit(cache=True)
def nhc_gate(nav, dt, min_speed, max_yaw_rate, max_lat_acc):
    """Whether the constraint holds now: rolling (speed ≥ ``min_speed``), not turning hard, not skidding (the
    last corrected increments over ``dt``)."""
    if not dt > 0.0:
        return False
    if math.hypot(nav[I_VEL], nav[I_VEL + 1]) < min_speed:
        return False
    return abs(nav[I_DTH + 2]) <= max_yaw_rate * dt and abs(nav[I_DV + 1]) <= max_lat_acc * dt
