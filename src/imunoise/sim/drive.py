"""Simulated urban drive with known truth: IMU (true and with errors), GNSS, reference
(docs/guide/theory.rst, 'Simulator').

Error injection (per sensor axis j, per IMU sample k, rates in rad/s or m/s²):

    r̃_k = (1 + s_j) r_k + b_j + e_{j,k} + w_k · a_j(v_k)

with r_k = Δθ_k/Δt (or Δv_k/Δt) the true mean rate over (t_{k−1}, t_k], s_j a scale-factor error, b_j the
turn-on bias, e_{j,k} a sample path of the axis' :class:`~imunoise.noise.model.Model` (per-sample parameters at
the IMU rate), and w_k·a_j(v) broadband vibration (white, std a_j·min(1, v/3 m/s), exactly zero on the
static epochs). The output increments are r̃_k Δt.

Motion-dependent errors (``DriveConfig.motion_noise``, :mod:`imunoise.sim.motion`): with a motion law the
path e_{j,k} is drawn with per-sample multipliers of its white and bias-process noise that grow with speed
and turn rate (1 on the static epochs), and the law replaces the vibration term (w_k·a_j ≡ 0: the law's
white multiplier is the vibration). ``motion_noise="none"`` makes the errors while moving exactly the static
model (nothing extra to learn in motion); ``None`` (the default of :class:`DriveConfig`) keeps the
vibration term alone, as before the motion laws.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.signal import lfilter

from imunoise.errors import ModelError
from imunoise.imu import ImuData
from imunoise.io.jsonutil import json_default
from imunoise.io.kfgins import (
    GnssData,
    Reference,
    write_gnss,
    write_imu,
    write_outages,
    write_reference,
)
from imunoise.nav.earth import OMEGA_E, radii
from imunoise.noise.model import Model
from imunoise.sim.drive_config import DriveConfig
from imunoise.sim.drive_plan import plan_drive
from imunoise.sim.drive_truth import truth_record
from imunoise.sim.imu_errors import models_to_json, resolve_imu_models, simulate_model_errors
from imunoise.sim.law_schedule import LawSchedule, law_schedule
from imunoise.sim.motion import NONE, modulated_errors, oracle_models, resolve_motion
from imunoise.sim.replay import load_recording, stretch
from imunoise.sim.trajectory import kinematics, simpson_increments

__all__ = ["DriveConfig", "SimulatedDrive", "simulate_drive", "plan_drive"]

SUBSTEPS = 4  # Simpson sub-steps per IMU interval (even)
STATIC_SPEED = 0.05  # m/s: slower than this and without rotation an epoch counts as static

# result container
# ----------------------------------------------------------------------------------------------


@dataclass(eq=False)
class SimulatedDrive:
    """Everything a simulated drive produces (times are GPS seconds of week, ``config.start_sow`` first).

    ``reference`` is the IMU (body origin) trajectory at ``ref_rate_hz``; ``reference_full`` at every IMU
    sample; ``reference_antenna`` the GNSS antenna point (position and velocity of the antenna, body
    attitude) at ``ref_rate_hz``, which is what ``ref.nav`` holds (as in the shared real drive).
    ``gnss`` is what a filter should use (outages removed iff ``config.remove_outages``); ``gnss_full``
    has every epoch (antenna position with noise and outliers). ``static_mask`` flags IMU samples whose
    whole interval has speed < 0.05 m/s and no rotation against the Earth (this includes the last creep
    of each braking, < 1 s; ``reference_full`` speed is exactly 0 at a stop).
    """

    config: DriveConfig
    imu: ImuData
    imu_true: ImuData
    gnss: GnssData
    gnss_full: GnssData
    reference: Reference
    reference_full: Reference
    reference_antenna: Reference
    static_mask: np.ndarray
    imu_models: dict[str, Model]
    truth: dict[str, Any]
    model_errors: np.ndarray  # (n, 6) model sample paths e_{j,k} [rad/s | m/s²], axes imu.AXES
    vibration: np.ndarray  # (n, 6) vibration part of the rate error
    # moving-regime per-axis models under the motion law (imunoise.sim.motion.oracle_models over this drive's
    # moving samples); the static models when there is no law or it is "none"
    moving_models: dict[str, Model] = field(default_factory=dict)
    # what the law injects per sample (imunoise.sim.law_schedule): the input of a law-aware filter; None without
    # a law
    law_schedule: LawSchedule | None = None

    @property
    def bias_true(self) -> np.ndarray:
        """(n, 6) true slowly varying rate error per axis: turn-on bias + model path (no vibration)."""
        b = np.concatenate([self.truth["turn_on_bias"]["gyro_rad_s"], self.truth["turn_on_bias"]["accel_m_s2"]])
        return self.model_errors + b

    def outage_windows(self, n: int, length_s: float, *, min_speed: float = 2.0,
                       lead_s: float = 0.0) -> list[tuple[float, float]]:
        """``n`` non-overlapping GNSS outage windows (start SOW, length) spread over the drive: the span
        from ``lead_s`` after the end of the static start to the final stop is cut into ``n`` equal sections
        and each window starts at the first epoch of its section with speed ≥ ``min_speed`` that leaves it
        room (if there is none, where the window covers the most road). ``lead_s``: GNSS-aided driving
        before the first window can start."""
        if not lead_s >= 0:
            raise ModelError(f"lead_s must be ≥ 0 s, got {lead_s}")
        a = self.truth["static_intervals"][0][1] + lead_s
        b = self.truth["static_intervals"][-1][0]
        if n < 1 or (b - a) / n < length_s:
            raise ModelError(
                f"cannot fit {n} outages of {length_s:g} s in the {max(b - a, 0.0):.0f} s of driving after the "
                f"{lead_s:g} s lead; shorten them, use fewer or a longer drive"
            )
        r = self.reference_full
        speed = np.linalg.norm(r.vel_ned, axis=1)
        dist = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(r.t))])
        dist_in = np.interp(r.t + length_s, r.t, dist) - dist  # distance covered by a window starting here
        edges = a + (b - a) * np.arange(n + 1) / n
        out = []
        for lo, hi in zip(edges[:-1], edges[1:], strict=True):
            fits = (r.t >= lo) & (r.t + length_s <= hi)
            ok = fits & (speed >= min_speed)
            if ok.any():
                start = float(r.t[np.argmax(ok)])
            else:  # the section is mostly a stop: take the window that covers the most road
                start = float(r.t[np.flatnonzero(fits)[np.argmax(dist_in[fits])]]) if fits.any() else float(lo)
            out.append((round(start, 6), float(length_s)))
        return out

    @property
    def outages_sow(self) -> list[tuple[float, float]]:
        """Outage windows in the data's time base (start SOW, duration)."""
        return [(self.config.start_sow + s, d) for s, d in self.config.outages]

    def write(self, out_dir: str | Path, *, compress: bool = False, name: str | None = None) -> Path:
        """Write into ``out_dir`` (KF-GINS text formats): ``imu.txt`` (with errors), ``imu_true.txt``,
        ``gnss.txt`` (``gnss_full.txt`` too when outages were removed), ``ref.nav`` (antenna point, like
        the shared real drive's reference), ``ref_imu.nav`` (IMU origin), ``outages.txt`` (when outages
        are set), ``truth.json`` and the ``dataset.json`` manifest (docs/guide/theory.rst, 'Interfaces'; ``ref_point``
        says which point ``ref`` is)."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        gz = ".gz" if compress else ""
        write_imu(out / f"imu.txt{gz}", self.imu)
        write_imu(out / f"imu_true.txt{gz}", self.imu_true)
        write_gnss(out / "gnss.txt", self.gnss)
        if len(self.gnss) != len(self.gnss_full):
            write_gnss(out / "gnss_full.txt", self.gnss_full)
        write_reference(out / f"ref.nav{gz}", self.reference_antenna)
        write_reference(out / f"ref_imu.nav{gz}", self.reference)
        manifest: dict[str, Any] = {
            "name": name or f"imunoise simulated drive (seed {self.config.seed}, {self.config.duration_s:g} s)",
            "imu": f"imu.txt{gz}",
            "imu_kind": "increments",
            "imu_rate_hz": self.config.imu_rate_hz,
            "gnss": "gnss.txt",
            "ref": f"ref.nav{gz}",
            "ref_point": "antenna",
            "ref_imu": f"ref_imu.nav{gz}",
            "lever_arm_m": list(self.config.lever_arm_m),
            "imu_time_offset_s": 0.0,
            "license": "CC0-1.0 (simulated by imunoise)",
            "truth": "truth.json",
            "imu_true": f"imu_true.txt{gz}",
            "simulated": True,
        }
        if self.config.outages:
            write_outages(out / "outages.txt", self.outages_sow, comment="start_sow duration_s (simulated drive)")
            manifest["outages"] = "outages.txt"
        (out / "truth.json").write_text(json.dumps(self.truth, indent=1, default=json_default))
        (out / "dataset.json").write_text(json.dumps(manifest, indent=1))
        return out


# ----------------------------------------------------------------------------------------------
# simulation
# ----------------------------------------------------------------------------------------------


def _offset_llh(llh: np.ndarray, d_ned: np.ndarray) -> np.ndarray:
    """llh displaced by small NED offsets (m), curvilinear first order (exact enough for metres)."""
    rm, rn = radii(llh[:, 0])
    out = llh.copy()
    out[:, 0] += d_ned[:, 0] / (rm + llh[:, 2])
    out[:, 1] += d_ned[:, 1] / ((rn + llh[:, 2]) * np.cos(llh[:, 0]))
    out[:, 2] -= d_ned[:, 2]
    return out


def _indices_at_rate(n_imu: int, imu_rate: float, rate: float, what: str) -> np.ndarray:
    """IMU sample indices of a sub-sampled stream at ``rate`` (which must divide the IMU rate)."""
    ratio = imu_rate / rate
    step = round(ratio)
    if step < 1 or abs(ratio - step) > 1e-9:
        nice = [r for r in (1, 2, 4, 5, 8, 10, 20, 25, 40, 50, 100) if abs(imu_rate / r - round(imu_rate / r)) < 1e-9]
        flag = "--gnss-rate" if what == "GNSS" else "--ref-rate (0 = IMU rate)"
        raise ModelError(
            f"{what} rate {rate:g} Hz must divide the IMU rate {imu_rate:g} Hz; e.g. {nice} Hz (CLI {flag})"
        )
    return np.arange(0, n_imu, step)


def simulate_drive(
    config: DriveConfig | None = None, imu_models: Any = None, seed: int | None = None
) -> SimulatedDrive:
    """Simulate an urban drive with known truth (docs/guide/theory.rst, 'Simulator'; equations in
    :mod:`imunoise.sim.trajectory` and this module's docstring).

    ``imu_models``: anything :func:`~imunoise.sim.imu_errors.resolve_imu_models` accepts (``None``: no
    stochastic errors; turn-on bias, scale factor and vibration still follow ``config``). ``seed``
    overrides ``config.seed``; the trajectory, the IMU errors and the GNSS noise use separate streams,
    so changing the IMU model keeps the same trajectory.

    Parameters
    ----------
    config : DriveConfig, optional
        The drive (default ``DriveConfig()``).
    imu_models : optional
        Stochastic error model of each IMU axis, e.g. a preset name or ``{"gyro": ..., "accel": ...}``.
    seed : int, optional
        Overrides ``config.seed``.

    Returns
    -------
    SimulatedDrive
        IMU with and without errors, GNSS, reference, truth and static mask; ``write(dir)`` saves it.
    """
    cfg = config or DriveConfig()
    seed = cfg.seed if seed is None else int(seed)
    ss_traj, ss_imu, ss_gnss, ss_bias = np.random.SeedSequence(seed).spawn(4)
    rng = np.random.default_rng(ss_traj)
    plan = plan_drive(cfg, rng)

    dt = 1.0 / cfg.imu_rate_hz
    n = int(round(cfg.duration_s * cfg.imu_rate_hz)) + 1  # samples at τ = 0, dt, ..., duration
    h = dt / SUBSTEPS
    tau = -dt + h * np.arange(n * SUBSTEPS + 1)
    llh0 = np.array([math.radians(cfg.start_llh[0]), math.radians(cfg.start_llh[1]), cfg.start_llh[2]])
    kin = kinematics(plan, tau, llh0)

    dth = simpson_increments(kin.omega_ib_b, h, SUBSTEPS)
    dv = simpson_increments(kin.f_b, h, SUBSTEPS)
    at = np.arange(1, n + 1) * SUBSTEPS  # fine index of each IMU sample time
    t = cfg.start_sow + tau[at]
    imu_true = ImuData(t=t, dtheta=dth, dv=dv)

    # static epochs: slower than 0.05 m/s on every sub-step of the interval and no yaw/pitch ramp
    spd = kin.speed
    moving_fine = (spd >= STATIC_SPEED) | (np.abs(kin.yaw_rate) > 0) | (np.abs(kin.pitch_rate) > 0)
    moving_block = moving_fine[:-1].reshape(n, SUBSTEPS).any(axis=1) | moving_fine[at]
    static_mask = ~moving_block

    # ---- IMU errors
    models = resolve_imu_models(imu_models, cfg.imu_rate_hz) if cfg.imu_noise is None else {}
    law = None if cfg.motion_noise is None else resolve_motion(cfg.motion_noise)
    moving_models = dict(models)
    replay = None
    m_white = m_bias = None
    if cfg.imu_noise is not None:  # real errors: no model, no vibration term (the recording is the truth)
        rec = load_recording(cfg.imu_noise)
        a, b = stretch(rec, seed - cfg.imu_noise_first, n, cfg.imu_rate_hz, reserve_s=cfg.imu_noise_reserve_s,
                       earlier=cfg.imu_noise_earlier, drives=cfg.imu_noise_drives)
        err = np.array(rec.errors[a:b])
        law = NONE if law is None else law
        replay = {**rec.describe(), "stretch_samples": [a, b], "stretch_s": [a / rec.rate_hz, b / rec.rate_hz],
                  "resampled": False}
    elif law is None or not law.modulates:
        err = simulate_model_errors(models, n, ss_imu)
    else:
        # body turn rate = norm of the Euler-angle rates: zero at rest, unlike ω_ib (Earth rate)
        turn = np.sqrt(kin.yaw_rate**2 + kin.pitch_rate**2 + kin.roll_rate**2)[at]
        # ‖f − g‖, the vehicle's acceleration: ‖dv_n/dt‖ (Coriolis and transport rate < 0.01 m/s² in a car)
        acc = np.linalg.norm(np.gradient(kin.vel, tau, axis=0), axis=1)[at]
        m_white, m_bias = law.multipliers(spd[at], turn, static_mask, accel=acc)
        err = modulated_errors(models, n, ss_imu, m_white, m_bias)
        moving_models = oracle_models(models, law, spd[at][~static_mask], turn[~static_mask],
                                      acc[~static_mask], rate_hz=cfg.imu_rate_hz)
    if law is not None and law.has_terms:
        # their own stream (spawn key 4, beside the drive's four): the other draws stay as without the terms
        err = err + law.additive_errors(t, static_mask, cfg.imu_rate_hz,
                                        np.random.SeedSequence(seed, spawn_key=(4,)))
        if not law.modulates and models:
            moving_models = oracle_models(models, law, rate_hz=cfg.imu_rate_hz)
    rb = np.random.default_rng(ss_bias)
    bias = np.concatenate([rb.normal(0, cfg.gyro_bias_sigma, 3), rb.normal(0, cfg.accel_bias_sigma, 3)])
    scale = rb.normal(0, cfg.scale_factor_sigma, 6) if cfg.scale_factor_sigma > 0 else np.zeros(6)
    if law is None:
        env = np.where(static_mask, 0.0, np.minimum(1.0, spd[at] / 3.0))
        vib_std = np.array([cfg.gyro_vibration] * 3 + [cfg.accel_vibration] * 3)
        vib = rb.standard_normal((n, 6)) * vib_std * env[:, None]
    else:  # the law's white multiplier is the vibration
        vib = np.zeros((n, 6))
    rate_true = np.column_stack([dth, dv]) / dt
    rate_meas = (1.0 + scale) * rate_true + bias + err + vib
    imu = ImuData(t=t, dtheta=rate_meas[:, :3] * dt, dv=rate_meas[:, 3:] * dt)

    # ---- reference (IMU origin)
    llh_k, vel_k, eul_k = kin.llh[at], kin.vel[at], kin.euler[at]
    week = np.full(n, cfg.gps_week)
    ref_full = Reference(t=t, llh=llh_k, vel_ned=vel_k, euler=eul_k, week=week)
    iref = (
        np.arange(n) if cfg.ref_rate_hz is None else _indices_at_rate(n, cfg.imu_rate_hz, cfg.ref_rate_hz, "reference")
    )
    reference = Reference(t=t[iref], llh=llh_k[iref], vel_ned=vel_k[iref], euler=eul_k[iref], week=week[iref])
    # antenna point: r + C_b^n l, velocity v + C_b^n (ω_eb^b × l) with ω_eb^b = ω_ib^b − C_n^b ω_ie^n
    lever = np.asarray(cfg.lever_arm_m, dtype=float)
    C_k = kin.C_bn[at[iref]]
    lat_r = llh_k[iref, 0]
    w_ie = OMEGA_E * np.column_stack([np.cos(lat_r), np.zeros_like(lat_r), -np.sin(lat_r)])
    w_eb = kin.omega_ib_b[at[iref]] - np.einsum("nji,nj->ni", C_k, w_ie)
    reference_antenna = Reference(
        t=t[iref],
        llh=_offset_llh(llh_k[iref], np.einsum("nij,j->ni", C_k, lever)),
        vel_ned=vel_k[iref] + np.einsum("nij,nj->ni", C_k, np.cross(w_eb, lever)),
        euler=eul_k[iref],
        week=week[iref],
    )

    # ---- GNSS at the antenna, white noise with the reported σ, gross outliers
    ig = _indices_at_rate(n, cfg.imu_rate_hz, cfg.gnss_rate_hz, "GNSS")
    rg = np.random.default_rng(ss_gnss)
    ant = np.einsum("nij,j->ni", kin.C_bn[at[ig]], lever)
    sig = np.asarray(cfg.gnss_sigma_m, dtype=float)
    noise = rg.standard_normal((ig.size, 3))
    if cfg.gnss_noise_tau_s > 0:  # stationary first-order Gauss-Markov with the same σ
        phi = math.exp(-1.0 / (cfg.gnss_noise_tau_s * cfg.gnss_rate_hz))
        noise[1:] *= math.sqrt(1.0 - phi * phi)
        noise = lfilter([1.0], [1.0, -phi], noise, axis=0)
    noise *= sig
    is_out = rg.random(ig.size) < cfg.outlier_rate
    k_out = int(is_out.sum())
    if k_out:
        mag = rg.uniform(*cfg.outlier_range_m, k_out)
        ang = rg.uniform(-math.pi, math.pi, k_out)
        noise[is_out, 0] += mag * np.cos(ang)
        noise[is_out, 1] += mag * np.sin(ang)
        noise[is_out, 2] += rg.normal(0.0, 0.5 * cfg.outlier_range_m[0], k_out)
    gllh = _offset_llh(llh_k[ig], ant + noise)
    gnss_full = GnssData(t=t[ig], llh=gllh, sigma_ned=np.tile(sig, (ig.size, 1)))
    gnss = gnss_full.without([(cfg.start_sow + s, d) for s, d in cfg.outages]) if cfg.remove_outages else gnss_full

    truth = truth_record(cfg, seed, plan, kin, at, models, bias, scale, t[ig][is_out], static_mask, t)
    truth["motion_noise"] = None if law is None else law.to_dict()
    truth["imu_noise"] = replay
    schedule = None if law is None else law_schedule(law, t, static_mask, m_white, m_bias)
    truth["models_moving"] = models_to_json(moving_models, cfg.imu_rate_hz)
    if law is not None:
        truth["vibration_std_at_speed"] = {"gyro_rad_s": 0.0, "accel_m_s2": 0.0, "full_at_mps": 3.0,
                                           "note": "replaced by the motion law's white multiplier"}
    return SimulatedDrive(
        config=cfg,
        imu=imu,
        imu_true=imu_true,
        gnss=gnss,
        gnss_full=gnss_full,
        reference=reference,
        reference_full=ref_full,
        reference_antenna=reference_antenna,
        static_mask=static_mask,
        imu_models=models,
        truth=truth,
        model_errors=err,
        vibration=vib,
        moving_models=moving_models,
        law_schedule=schedule,
    )
