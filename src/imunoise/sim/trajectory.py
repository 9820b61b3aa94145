"""Urban-drive trajectory with exact strapdown kinematics (docs/guide/theory.rst, 'Simulator').

The vehicle is described by four smooth scalar channels of time: speed v, yaw ψ, pitch θ (road grade)
and roll φ. Speed, yaw and pitch are sums of non-overlapping quintic "smoothstep" ramps
s(x) = 10x³ − 15x⁴ + 6x⁵ (zero 1st and 2nd derivative at both ends: acceleration, jerk, turn rate and
turn acceleration all start and end at zero). Roll follows the lateral acceleration, φ = −k·v·ψ̇ (the
body leans out of the turn). The velocity is along the body x axis (no side slip):

    v^n = v · C_b^n e_x = v [cos θ cos ψ, cos θ sin ψ, −sin θ]

Position is the integral of v^n in curvilinear coordinates (lat' = v_N/(R_M+h), lon' = v_E/((R_N+h)cos
lat), h' = −v_D) on a fine grid (cumulative Simpson). The IMU signals follow from the strapdown
equations in NED (Groves 2013, Eqs. 5.46, 5.54; Shin 2001, Eq. 2.46):

    ω_ib^b = ω_nb^b + C_n^b (ω_ie^n + ω_en^n),
    ω_nb^b = [φ̇ − ψ̇ sin θ,  θ̇ cos φ + ψ̇ sin φ cos θ,  −θ̇ sin φ + ψ̇ cos φ cos θ]   (ZYX Euler rates),
    f^b    = C_n^b (v̇^n − g^n + (2ω_ie^n + ω_en^n) × v^n),  g^n = [0, 0, g(lat, h)],

and the increments Δθ_k = ∫ω_ib^b dt, Δv_k = ∫f^b dt over (t_{k−1}, t_k] are composite-Simpson integrals
on S sub-steps per IMU interval. That is what an ideal integrating IMU outputs; the coning/sculling terms
of the mechanization recover the rest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import cumulative_simpson

from imunoise.errors import ModelError
from imunoise.nav.earth import OMEGA_E, gravity, radii

__all__ = ["Ramps", "DrivePlan", "Kinematics", "kinematics", "euler_to_dcm_many"]


# ----------------------------------------------------------------------------------------------
# smooth ramps
# ----------------------------------------------------------------------------------------------


def _smoothstep(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """s(x), s'(x), s''(x) of the quintic smoothstep on [0, 1]."""
    x2 = x * x
    s = x2 * x * (10.0 - 15.0 * x + 6.0 * x2)
    d1 = 30.0 * x2 * (1.0 - x) ** 2
    d2 = 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x)
    return s, d1, d2


@dataclass
class Ramps:
    """A channel made of non-overlapping quintic ramps between constant levels.

    Flat parts hold the exact target level (a stop has speed exactly 0).
    """

    level0: float
    starts: list[float] = field(default_factory=list)
    durs: list[float] = field(default_factory=list)
    frm: list[float] = field(default_factory=list)
    to: list[float] = field(default_factory=list)

    @property
    def level(self) -> float:
        return self.to[-1] if self.to else self.level0

    @property
    def end(self) -> float:
        return self.starts[-1] + self.durs[-1] if self.starts else -math.inf

    def add(self, t0: float, dur: float, to: float) -> float:
        """Ramp from the current level to ``to`` over [t0, t0 + dur]; returns the end time."""
        if t0 < self.end - 1e-9:
            raise ModelError(f"ramp at {t0} overlaps the previous one ending at {self.end}")
        if dur <= 0:
            raise ModelError(f"ramp duration must be > 0 s, got {dur}")
        self.starts.append(float(t0))
        self.durs.append(float(dur))
        self.frm.append(self.level)
        self.to.append(float(to))
        return t0 + dur

    def eval(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Value and first two time derivatives at times ``t``."""
        t = np.asarray(t, dtype=float)
        if not self.starts:
            z = np.zeros_like(t)
            return np.full_like(t, self.level0), z, z.copy()
        starts = np.asarray(self.starts)
        durs = np.asarray(self.durs)
        frm = np.asarray(self.frm)
        to = np.asarray(self.to)
        idx = np.searchsorted(starts, t, side="right") - 1
        before = idx < 0
        i = np.maximum(idx, 0)
        x = np.clip((t - starts[i]) / durs[i], 0.0, 1.0)
        s, d1, d2 = _smoothstep(x)
        delta = to[i] - frm[i]
        val = np.where(x >= 1.0, to[i], frm[i] + delta * s)
        val = np.where(before, self.level0, val)
        v1 = np.where(before, 0.0, delta * d1 / durs[i])
        v2 = np.where(before, 0.0, delta * d2 / durs[i] ** 2)
        return val, v1, v2


@dataclass
class DrivePlan:
    """The scripted manoeuvres of one drive (times in s from the start of the recording)."""

    duration: float
    speed: Ramps
    yaw: Ramps
    pitch: Ramps
    roll_gain: float  # rad per m/s² of lateral acceleration
    stops: list[tuple[float, float]]  # traffic-light stops (vehicle at rest)
    static_intervals: list[tuple[float, float]]  # every interval at rest (initial, stops, final)
    turns: list[dict]  # {"t0", "duration", "angle_deg", "peak_rate_deg_s", "kind"}


# ----------------------------------------------------------------------------------------------
# kinematics on a fine grid
# ----------------------------------------------------------------------------------------------


def euler_to_dcm_many(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """C_b^n (n, 3, 3) for ZYX Euler angles, the vectorised form of ``imunoise.nav.earth.euler_to_dcm``."""
    sr, cr = np.sin(roll), np.cos(roll)
    sp, cp = np.sin(pitch), np.cos(pitch)
    sy, cy = np.sin(yaw), np.cos(yaw)
    C = np.empty(roll.shape + (3, 3))
    C[..., 0, 0] = cp * cy
    C[..., 0, 1] = -cr * sy + sr * sp * cy
    C[..., 0, 2] = sr * sy + cr * sp * cy
    C[..., 1, 0] = cp * sy
    C[..., 1, 1] = cr * cy + sr * sp * sy
    C[..., 1, 2] = -sr * cy + cr * sp * sy
    C[..., 2, 0] = -sp
    C[..., 2, 1] = sr * cp
    C[..., 2, 2] = cr * cp
    return C


@dataclass
class Kinematics:
    """Truth on the fine grid ``tau`` (s from start): position, velocity, attitude, IMU signals."""

    tau: np.ndarray
    llh: np.ndarray
    vel: np.ndarray
    euler: np.ndarray
    C_bn: np.ndarray
    speed: np.ndarray
    accel: np.ndarray  # dv/dt along track, m/s²
    yaw_rate: np.ndarray  # ψ̇, rad/s
    pitch_rate: np.ndarray
    roll_rate: np.ndarray
    omega_ib_b: np.ndarray
    f_b: np.ndarray


def kinematics(plan: DrivePlan, tau: np.ndarray, llh0: np.ndarray) -> Kinematics:
    """Evaluate the plan on a uniform grid ``tau`` and integrate position from ``llh0`` at ``tau[0]``
    (module docstring equations)."""
    v, vdot, _ = plan.speed.eval(tau)
    psi, psid, psidd = plan.yaw.eval(tau)
    th, thd, _ = plan.pitch.eval(tau)
    k = plan.roll_gain
    phi = -k * v * psid
    phid = -k * (vdot * psid + v * psidd)

    cth, sth = np.cos(th), np.sin(th)
    cps, sps = np.cos(psi), np.sin(psi)
    u = np.column_stack([cth * cps, cth * sps, -sth])
    udot = np.column_stack([-sth * thd * cps - cth * sps * psid, -sth * thd * sps + cth * cps * psid, -cth * thd])
    vel = v[:, None] * u
    vdot_n = vdot[:, None] * u + v[:, None] * udot

    # position by cumulative Simpson; R_M, R_N depend (weakly) on latitude, so iterate twice
    dx = float(tau[1] - tau[0])
    h = llh0[2] + cumulative_simpson(-vel[:, 2], dx=dx, initial=0.0)
    lat = np.full_like(tau, llh0[0])
    for _ in range(3):
        rm, rn = radii(lat)
        lat = llh0[0] + cumulative_simpson(vel[:, 0] / (rm + h), dx=dx, initial=0.0)
    rm, rn = radii(lat)
    lon = llh0[1] + cumulative_simpson(vel[:, 1] / ((rn + h) * np.cos(lat)), dx=dx, initial=0.0)
    llh = np.column_stack([lat, lon, h])

    w_ie = OMEGA_E * np.column_stack([np.cos(lat), np.zeros_like(lat), -np.sin(lat)])
    w_en = np.column_stack([vel[:, 1] / (rn + h), -vel[:, 0] / (rm + h), -vel[:, 1] * np.tan(lat) / (rn + h)])
    g = gravity(lat, h)
    C = euler_to_dcm_many(phi, th, psi)

    sph, cph = np.sin(phi), np.cos(phi)
    w_nb = np.column_stack([phid - psid * sth, thd * cph + psid * sph * cth, -thd * sph + psid * cph * cth])
    w_in = w_ie + w_en
    w_ib = w_nb + np.einsum("nji,nj->ni", C, w_in)
    acc_n = vdot_n + np.cross(2.0 * w_ie + w_en, vel)
    acc_n[:, 2] -= g
    f_b = np.einsum("nji,nj->ni", C, acc_n)
    return Kinematics(
        tau=tau,
        llh=llh,
        vel=vel,
        euler=np.column_stack([phi, th, np.angle(np.exp(1j * psi))]),
        C_bn=C,
        speed=v,
        accel=vdot,
        yaw_rate=psid,
        pitch_rate=thd,
        roll_rate=phid,
        omega_ib_b=w_ib,
        f_b=f_b,
    )


def simpson_increments(x: np.ndarray, dx: float, sub: int) -> np.ndarray:
    """Integrals of ``x`` (rows on a uniform grid, step dx) over consecutive blocks of ``sub`` steps
    (composite Simpson, ``sub`` even): row k integrates grid points k·sub .. (k+1)·sub."""
    if sub % 2:
        raise ModelError(f"composite Simpson needs an even number of sub-steps, got sub={sub}")
    n = (x.shape[0] - 1) // sub
    w = np.ones(sub + 1)
    w[1:-1:2] = 4.0
    w[2:-1:2] = 2.0
    w *= dx / 3.0
    out = np.zeros((n,) + x.shape[1:])
    for j in range(sub + 1):
        out += w[j] * x[j : j + n * sub : sub][:n]
    return out
