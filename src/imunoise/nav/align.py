"""Static coarse alignment and initial biases (docs/guide/theory.rst, 'Navigation filter'; the KF-GINS initialisation of
the shared drive).

* roll, pitch from the mean specific force of a static window: at rest f^b = C_n^b [0, 0, −g], so
  roll = atan2(−f_y, −f_z), pitch = atan2(f_x, √(f_y² + f_z²));
* yaw from the first GNSS course with speed > ``min_speed`` (differenced positions), propagated back to
  the start time with the bias-corrected gyros (Euler-rate kinematics ψ̇ = (ω_y sin φ + ω_z cos φ)/cos θ),
  or given;
* initial gyro bias = static mean of the gyros minus the Earth rate projected into the body frame.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from imunoise.errors import DataError
from imunoise.nav.earth import euler_to_dcm, llh_to_ned, omega_ie_n, radii
from imunoise.nav.ekf import InitialState

log = logging.getLogger(__name__)

__all__ = ["level", "gnss_course", "check_static_window", "coarse_align"]


def level(accel_mean: np.ndarray) -> tuple[float, float]:
    """(roll, pitch) in rad from a mean specific force (m/s², body FRD) at rest."""
    f = np.asarray(accel_mean, dtype=float)
    return float(math.atan2(-f[1], -f[2])), float(math.atan2(f[0], math.hypot(f[1], f[2])))


def gnss_course(gnss, t_from: float, min_speed: float = 3.0) -> tuple[float, float, float] | None:
    """(time, course rad, speed m/s) of the vehicle at the first GNSS epoch after ``t_from`` faster than
    ``min_speed``.

    The speed test uses central differences of consecutive fixes; the course is the direction of the
    displacement from that epoch to the first later fix at least max(30·σ_h, 3 m) away (σ_h the
    horizontal GNSS σ), so position noise adds ≲ 3° even for metre-level fixes; its time is the middle
    of that span.
    """
    t = np.asarray(gnss.t, dtype=float)
    m = t >= t_from - 1.0
    t, llh = t[m], np.asarray(gnss.llh, dtype=float)[m]
    sig = np.asarray(gnss.sigma_ned, dtype=float)[m]
    if t.size < 3:
        return None
    ned = llh_to_ned(llh, llh[0])
    v = np.gradient(ned, t, axis=0)
    speed = np.hypot(v[:, 0], v[:, 1])
    ok = np.flatnonzero((speed > min_speed) & (t >= t_from))
    if ok.size == 0:
        return None
    i = int(ok[0])
    need = max(30.0 * float(np.hypot(sig[i, 0], sig[i, 1])), 3.0)
    d = np.hypot(ned[i:, 0] - ned[i, 0], ned[i:, 1] - ned[i, 1])
    far = np.flatnonzero(d >= need)
    if far.size == 0:
        return float(t[i]), float(math.atan2(v[i, 1], v[i, 0])), float(speed[i])
    j = i + int(far[0])
    course = math.atan2(ned[j, 1] - ned[i, 1], ned[j, 0] - ned[i, 0])
    return float(0.5 * (t[i] + t[j])), float(course), float(speed[i])


STILL_SHARE_MOVING_MAX = 0.10
"""Share of a levelling window the static detector may call moving (doors, a passenger) before it is refused."""

LAMBDA0_FLOOR = 1e-3
"""Smallest λ0 [m/s²] of the levelling-window check (noise-free data would give 0)."""

GNSS_STILL_RADIUS_M = 10.0
"""GNSS antenna displacement inside a levelling window above which the window is refused as driving."""


def check_static_window(
    t: np.ndarray, accel: np.ndarray, gnss, ta: float, tb: float, option: str = "--static-duration"
) -> None:
    """Refuse a levelling window [ta, tb] that is not still, with the measured motion
    (docs/guide/theory.rst, 'Static detection' detector test).

    The static detector's statistic T (paper Eq. 9: moving std of accel x and y over N = 100 samples) is
    computed over the window; λ0 is learned on its first third by the detector's rule (2 × median T,
    :func:`imunoise.detect.learn_lambda0`, at least :data:`LAMBDA0_FLOOR`), and epochs with T above the
    adaptive threshold's ceiling 2λ0 count as moving. More than :data:`STILL_SHARE_MOVING_MAX` of the window
    moving, or GNSS fixes inside it spread over more than max(:data:`GNSS_STILL_RADIUS_M`, 10 σ_h), is
    refused: levelling over driving turns accelerations into tilt (and a wrong gyro bias and yaw).

    Raises
    ------
    DataError
        Naming ``option``, the window, the motion measured and the still span at its start.
    """
    from imunoise.detect import moving_std

    m = (t >= ta) & (t <= tb)
    n_win = 100
    acc = accel[m]
    tw = t[m]
    dur = tb - ta
    if acc.shape[0] >= 3 * n_win:
        T = moving_std(acc[:, :2], n_win)[n_win - 1 :]
        # λ0 by the detector's rule on the first third, with a floor: noise-free (simulated) data have T = 0
        lam0 = max(2.0 * float(np.median(T[: max(T.shape[0] // 3, n_win)])), LAMBDA0_FLOOR)
        tt = tw[n_win - 1 :]
        moving = (T > 2.0 * lam0).any(axis=1)
        share = float(moving.mean())
        if share > STILL_SHARE_MOVING_MAX:
            k = int(np.argmax(moving))  # the window is still up to here
            raise DataError(
                f"{option} {dur:g}: the IMU is not still over the levelling window [{ta:.3f}, {tb:.3f}] s: the "
                f"static detector's statistic (Eq. 9, moving std of accel x/y) exceeds 2λ0 = {2 * lam0:.3g} m/s² "
                f"on {100 * share:.0f} % of it (peak {float(np.nanmax(T)):.3g} m/s², first at {tt[k] - ta:.1f} s); "
                f"give the length of the stop at the start (≤ {max(tt[k] - ta, 0.0):.1f} s)"
            )
    gt = np.asarray(gnss.t, dtype=float)
    g = (gt >= ta) & (gt <= tb)
    if np.count_nonzero(g) >= 2:
        llh = np.asarray(gnss.llh, dtype=float)[g]
        ned = llh_to_ned(llh, llh[0])
        spread = float(np.hypot(ned[:, 0], ned[:, 1]).max())
        sig = np.asarray(gnss.sigma_ned, dtype=float)[g]
        allowed = max(GNSS_STILL_RADIUS_M, 10.0 * float(np.median(np.hypot(sig[:, 0], sig[:, 1]))))
        if spread > allowed:
            k = int(np.argmax(np.hypot(ned[:, 0], ned[:, 1]) > allowed))
            raise DataError(
                f"{option} {dur:g}: the GNSS antenna moves {spread:.0f} m inside the levelling window "
                f"[{ta:.3f}, {tb:.3f}] s (beyond {allowed:.0f} m at {gt[g][k] - ta:.1f} s); give the length of the "
                "stop at the start"
            )


def _interp_llh(gnss, t0: float) -> np.ndarray:
    t = np.asarray(gnss.t, dtype=float)
    llh = np.asarray(gnss.llh, dtype=float)
    if t0 < t[0] - 1.0 or t0 > t[-1] + 1.0:
        raise DataError(f"no GNSS fix near the start time {t0:.3f} (GNSS spans {t[0]:.3f}..{t[-1]:.3f})")
    return np.array([np.interp(t0, t, llh[:, i]) for i in range(3)])


def coarse_align(
    imu,
    gnss,
    t0: float | None = None,
    *,
    static_window: tuple[float, float] | None = None,
    static_duration: float = 30.0,
    yaw: float | None = None,
    lever_arm=(0.0, 0.0, 0.0),
    min_speed: float = 3.0,
    estimate_gyro_bias: bool = True,
    check_still: bool = False,
) -> InitialState:
    """Initial state at ``t0`` (default: the first IMU epoch covered by GNSS) for a vehicle at rest.

    ``static_window`` (t_a, t_b) is the still period used for levelling and the gyro bias (default: the
    first ``static_duration`` s of the IMU data). Position is the GNSS antenna position at t0 moved by
    the lever arm to the IMU; velocity 0 (the window must be static; a warning is logged when the
    accelerometers say otherwise; with ``check_still`` a window the static detector or the GNSS shows
    moving is refused, :func:`check_static_window`).
    """
    t = np.asarray(imu.t, dtype=float)
    gyro, accel = imu.rates()
    if t0 is None:
        t0 = max(float(t[0]), float(np.asarray(gnss.t)[0]))
    if not (t[0] <= t0 < t[-1]):
        raise DataError(f"start time {t0:.3f} is outside the IMU data [{t[0]:.3f}, {t[-1]:.3f}]")
    ta, tb = static_window if static_window is not None else (t[0], t[0] + static_duration)
    m = (t >= ta) & (t <= tb)
    if m.sum() < 10:
        raise DataError(f"static window {ta:.3f}..{tb:.3f} holds {m.sum()} IMU samples; need ≥ 10")
    if check_still:
        check_static_window(t, accel, gnss, ta, tb)
    f_mean = accel[m].mean(axis=0)
    w_mean = gyro[m].mean(axis=0)
    g_norm = float(np.linalg.norm(f_mean))
    if abs(g_norm - 9.8) > 0.3:
        log.warning("mean specific force in the static window is %.3f m/s² (not ~9.8): is it static, SI?", g_norm)
    roll, pitch = level(f_mean)
    llh_ant = _interp_llh(gnss, t0)
    if yaw is None:
        found = gnss_course(gnss, t0, min_speed)
        if found is None:
            raise DataError(
                f"no GNSS course with speed > {min_speed:g} m/s after the start {t0:.3f} s (the GNSS track never "
                "moves that fast); give the initial heading with --yaw DEG"
            )
        tc, course, _ = found
        # yaw rate from the bias-corrected gyros between t0 and the course epoch
        mk = (t > t0) & (t <= tc)
        dt = np.diff(t, prepend=t[0])[mk]
        wb = gyro[mk] - (w_mean if estimate_gyro_bias else 0.0)
        # Earth-rate residual is removed with the bias; the heading rate is ψ̇ = (ω_y sin φ + ω_z cos φ)/cos θ
        psi_dot = (wb[:, 1] * math.sin(roll) + wb[:, 2] * math.cos(roll)) / math.cos(pitch)
        yaw = course - float(np.sum(psi_dot * dt))
        yaw = math.atan2(math.sin(yaw), math.cos(yaw))
        log.info("yaw %.2f° from the GNSS course at t=%.2f propagated back %.1f s", math.degrees(yaw), tc, tc - t0)
    C = euler_to_dcm(roll, pitch, yaw)
    bg = np.zeros(3)
    if estimate_gyro_bias:
        bg = w_mean - C.T @ omega_ie_n(llh_ant[0])
    # IMU position = antenna − C·lever (NED offset converted to llh)
    d = C @ np.asarray(lever_arm, dtype=float)
    rm, rn = radii(llh_ant[0])
    llh = llh_ant.copy()
    llh[0] -= d[0] / (rm + llh[2])
    llh[1] -= d[1] / ((rn + llh[2]) * math.cos(llh[0]))
    llh[2] += d[2]
    return InitialState(float(t0), llh, np.zeros(3), np.array([roll, pitch, yaw]), bg, np.zeros(3))
