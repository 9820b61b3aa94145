"""How the IMU sits in the vehicle: the check of a run's mounting and the rotation that corrects it
(docs/guide/theory.rst, 'Conventions' and 'Navigation filter').

The filter aligns its heading with the GNSS course and its non-holonomic constraints zero the body's lateral and
vertical velocity: both take the IMU's x axis as the vehicle's forward axis. An IMU turned in its mount breaks
that silently (a 90° yaw: heading off by 90°, a hundred metres of error with RTK fixes).

The mounting is ``C_s^v`` (IMU → vehicle FRD), given as ZYX Euler angles roll, pitch, yaw [deg] like an
attitude: ``--mount-rpy 0,0,90`` is an IMU whose x axis points to the vehicle's right. :func:`rotate_imu` turns
the increments into the vehicle frame once, so alignment, NHC and ZUPT see a vehicle-frame IMU.

What the data tell (:func:`estimate_mounting`):

* **roll, pitch** — gravity at the first stop gives the IMU's tilt to the local level, which is the mounting
  tilt plus the slope and bank of the road at that stop: they cannot be told apart from one stop. A tilt above
  the threshold (10°, a 18 % grade) is reported as a tilted mounting; a few degrees are not detectable.
* **yaw** — with the tilt of the stop removed, the horizontal specific force is the vehicle's acceleration
  turned by −yaw; the GNSS track gives that acceleration in the vehicle frame (along the course, and across it
  in turns). Their angle, weighted by the acceleration, is the mounting yaw. It needs speed changes or turns
  (a drive at constant speed on a straight road does not show it); slopes met while accelerating bias it.
  Both sides are triangular averages over ±h of the GNSS epoch (the second difference of positions, and of
  the double integral of the IMU's velocity increments), h wide enough that the GNSS noise stays ≲ 0.2 m/s².
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from imunoise.errors import ModelError
from imunoise.imu import ImuData
from imunoise.nav.align import level
from imunoise.nav.earth import euler_to_dcm

__all__ = ["MountEstimate", "estimate_mounting", "mount_matrix", "mounting_warning", "parse_mount_rpy",
           "rotate_imu", "sideslip_deg", "MOUNT_THRESHOLD_DEG"]

MOUNT_THRESHOLD_DEG = 10.0
"""A mounting angle above this is reported (a stop on a steeper slope than 18 % is rare)."""

ACCEL_NOISE = 0.2
"""m/s²: the largest GNSS acceleration noise (second difference of positions) the yaw estimate works with."""


def parse_mount_rpy(text: str) -> tuple[float, float, float]:
    """``"R,P,Y"`` [deg] of ``--mount-rpy`` → (roll, pitch, yaw) [deg]; refused in one line naming the option."""
    try:
        v = tuple(float(x) for x in str(text).replace(" ", "").split(","))
    except ValueError:
        v = ()
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise ModelError(f"--mount-rpy takes roll,pitch,yaw in degrees (e.g. --mount-rpy 0,0,90), got {text!r}")
    return v  # type: ignore[return-value]


def mount_matrix(rpy_deg) -> np.ndarray:
    """``C_s^v`` (IMU → vehicle) of the mounting angles roll, pitch, yaw [deg] (ZYX, as an attitude)."""
    r, p, y = (math.radians(float(a)) for a in rpy_deg)
    return np.asarray(euler_to_dcm(r, p, y))


def rotate_imu(imu: ImuData, C_sv: np.ndarray) -> ImuData:
    """``imu`` in the vehicle frame: every increment (or rate) turned by the constant ``C_sv`` (exact: a fixed
    rotation commutes with the integration over a sample)."""
    C = np.asarray(C_sv, dtype=float)
    return ImuData(imu.t, imu.dtheta @ C.T, imu.dv @ C.T, kind=imu.kind, frame=imu.frame)


@dataclass(frozen=True)
class MountEstimate:
    """What the data say of the mounting (module docstring): angles [deg]; ``yaw_deg`` None when the drive
    shows too little acceleration; ``yaw_spread_deg`` the acceleration-weighted circular spread of the
    per-epoch angles; ``epochs`` GNSS epochs used; ``half_window_s`` h."""

    roll_deg: float
    pitch_deg: float
    yaw_deg: float | None
    yaw_spread_deg: float | None
    epochs: int
    half_window_s: float

    def as_dict(self) -> dict:
        return {"roll_deg": self.roll_deg, "pitch_deg": self.pitch_deg, "yaw_deg": self.yaw_deg,
                "yaw_spread_deg": self.yaw_spread_deg, "yaw_epochs": self.epochs, "half_window_s": self.half_window_s}


def _double_integral(t: np.ndarray, dv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Times and ∫∫ f dt² of the velocity increments ``dv`` (n, 2) over (t_{k-1}, t_k]: the IMU side of the
    second difference (trapezoid of the running velocity sum)."""
    vel = np.cumsum(dv, axis=0)
    vel = np.vstack([np.zeros((1, dv.shape[1])), vel])
    tt = np.concatenate([[t[0] - (t[1] - t[0])], t])
    step = np.diff(tt)[:, None]
    pos = np.vstack([np.zeros((1, dv.shape[1])), np.cumsum(0.5 * (vel[1:] + vel[:-1]) * step, axis=0)])
    return tt, pos


def estimate_mounting(
    t: np.ndarray,
    dv: np.ndarray,
    static: np.ndarray,
    gnss_t: np.ndarray,
    gnss_ned: np.ndarray,
    sigma_h: float,
    *,
    min_speed: float = 3.0,
    min_accel: float = 0.3,
) -> MountEstimate:
    """The mounting the data show (module docstring).

    Parameters
    ----------
    t, dv : numpy.ndarray
        IMU times [s] (n,) and velocity increments [m/s] (n, 3) over (t_{k-1}, t_k], IMU axes.
    static : numpy.ndarray
        (n,) bool: the samples of the first stop (levelling).
    gnss_t, gnss_ned : numpy.ndarray
        GNSS epochs [s] and antenna positions NED [m] (m,), (m, 3), same time base.
    sigma_h : float
        Typical horizontal GNSS σ [m] (sets the averaging half-window h).
    min_speed, min_accel : float
        Epochs used for the yaw: speed > ``min_speed`` [m/s] and GNSS acceleration > ``min_accel`` [m/s²].
    """
    t = np.asarray(t, dtype=float)
    dv = np.asarray(dv, dtype=float)
    dt_imu = np.diff(t)
    f_static = dv[static][1:].sum(axis=0) / max(float(dt_imu[static[1:]].sum()), 1e-12)
    roll, pitch = level(f_static)
    R_lev = euler_to_dcm(roll, pitch, 0.0)  # IMU → its own levelled frame (heading of the IMU's x)
    dv_lev = dv @ np.asarray(R_lev).T

    gt = np.asarray(gnss_t, dtype=float)
    ned = np.asarray(gnss_ned, dtype=float)
    step = float(np.median(np.diff(gt))) if gt.size > 1 else 1.0
    h_noise = math.sqrt(math.sqrt(6.0) * max(float(sigma_h), 1e-3) / ACCEL_NOISE)
    m = max(1, int(round(max(h_noise, step) / step)))  # h = m GNSS steps
    h = m * step
    yaw, spread, n = None, None, 0
    if gt.size > 2 * m:
        k = np.arange(m, gt.size - m)
        ok = (np.abs(gt[k + m] - gt[k] - h) < 0.25 * step) & (np.abs(gt[k] - gt[k - m] - h) < 0.25 * step)
        ok &= (gt[k - m] >= t[0]) & (gt[k + m] <= t[-1])
        k = k[ok]
        a_n = (ned[k + m, :2] - 2.0 * ned[k, :2] + ned[k - m, :2]) / h**2
        v_n = (ned[k + m, :2] - ned[k - m, :2]) / (2.0 * h)
        speed = np.hypot(v_n[:, 0], v_n[:, 1])
        course = np.arctan2(v_n[:, 1], v_n[:, 0])
        # the vehicle's acceleration in its own frame (forward, right): a car moves along its course
        z_v = (a_n[:, 0] + 1j * a_n[:, 1]) * np.exp(-1j * course)
        tt, pos = _double_integral(t, dv_lev[:, :2])
        s = np.column_stack([np.interp(x, tt, pos[:, i]) for x in (gt[k - m], gt[k], gt[k + m]) for i in (0, 1)])
        f_h = (s[:, 4:6] - 2.0 * s[:, 2:4] + s[:, 0:2]) / h**2  # triangular mean of f over ±h, levelled IMU axes
        z_s = f_h[:, 0] + 1j * f_h[:, 1]
        use = (speed > min_speed) & (np.abs(z_v) > min_accel)
        n = int(np.count_nonzero(use))
        if n >= 10:
            c = z_v[use] * np.conj(z_s[use])  # z_s = e^{-iψ} z_v: each term |z|² e^{iψ}
            yaw = math.degrees(float(np.angle(c.sum())))
            w = np.abs(c) / np.abs(c).sum()
            r = float(np.abs(np.sum(w * c / np.abs(c))))
            spread = math.degrees(math.sqrt(max(-2.0 * math.log(max(r, 1e-12)), 0.0)))
    return MountEstimate(math.degrees(roll), math.degrees(pitch), yaw, spread, n, h)


def _wrap(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


SNAP_DEG = 5.0
"""An angle this close to a multiple of 90° is given as that multiple in the fix: IMUs are mostly mounted turned by
right angles, and the yaw estimate scatters by a few degrees (docs/evidence/imu_mounting.md)."""


def _snap(deg: float) -> float:
    right = 90.0 * round(deg / 90.0)
    return right if abs(deg - right) <= SNAP_DEG else deg


def mounting_warning(est: MountEstimate, source: str, threshold_deg: float = MOUNT_THRESHOLD_DEG,
                     given: tuple[float, float, float] | None = None) -> str | None:
    """One line when a mounting angle exceeds ``threshold_deg``: the angles and the ``--mount-rpy`` that corrects
    them (added to ``given``, the mounting already applied; tilt and yaw each only above the threshold; an angle
    within :data:`SNAP_DEG` of a right angle given as the right angle), else None."""
    roll, pitch = _wrap(est.roll_deg), _wrap(est.pitch_deg)
    yaw = 0.0 if est.yaw_deg is None else _wrap(est.yaw_deg)
    if max(abs(roll), abs(pitch), abs(yaw)) <= threshold_deg:
        return None
    tilt = max(abs(roll), abs(pitch)) > threshold_deg
    yawed = abs(yaw) > threshold_deg
    # the residual mounting of the data as given to the filter, after the rotation already applied (``given``):
    # x_v = C_found C_given x_imu; a tilt below the threshold is the road's as much as the mount's: left out
    found = mount_matrix((roll if tilt else 0.0, pitch if tilt else 0.0, yaw if yawed else 0.0))
    from imunoise.nav.earth import dcm_to_euler

    fix = found @ mount_matrix(given or (0.0, 0.0, 0.0))
    r, p, y = (round(_snap(math.degrees(float(a)))) + 0 for a in dcm_to_euler(fix))
    what = []
    if tilt:
        what.append(f"tilted roll {round(roll) + 0}°, pitch {round(pitch) + 0}° at the first stop "
                    "(or parked on that slope)")
    if yawed:
        what.append(f"turned {round(yaw) + 0}° in yaw (the acceleration along the GNSS track in its axes, {est.epochs} "
                    f"epochs, spread {est.yaw_spread_deg:.0f}°)")
    return (f"IMU {source} looks mounted {' and '.join(what)}: the heading from the GNSS course, --nhc and the "
            f"attitude written take x forward, z down; give --mount-rpy {r},{p},{y}")


def sideslip_deg(euler: np.ndarray, vel_ned: np.ndarray, min_speed: float = 3.0) -> float | None:
    """The filter's own view of the mounting (the NHC residual's direction): the median angle [deg] of the
    horizontal velocity in the body axes, atan2(v_y, v_x), while faster than ``min_speed`` [m/s]; ≈ 0 for an
    IMU with x forward, ≈ −yaw for one turned by yaw, when the filter's heading has converged. None when
    never that fast."""
    e = np.asarray(euler, dtype=float)
    v = np.asarray(vel_ned, dtype=float)
    fast = np.hypot(v[:, 0], v[:, 1]) > min_speed
    if not fast.any():
        return None
    ang = []
    for (r, p, y), vn in zip(e[fast][::10], v[fast][::10]):  # every 10th sample: a median, not a sum
        vb = np.asarray(euler_to_dcm(r, p, y)).T @ vn
        ang.append(math.atan2(vb[1], vb[0]))
    a = np.asarray(ang)
    return math.degrees(float(np.angle(np.median(np.cos(a)) + 1j * np.median(np.sin(a)))))
