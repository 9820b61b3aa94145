"""Simulated urban drive with known truth: IMU (true and with errors), GNSS, reference (SPEC §10).

Error injection (per sensor axis j, per IMU sample k, rates in rad/s or m/s²):

    r̃_k = (1 + s_j) r_k + b_j + e_{j,k} + w_k · a_j(v_k)

with r_k = Δθ_k/Δt (or Δv_k/Δt) the true mean rate over (t_{k−1}, t_k], s_j a scale-factor error, b_j the
turn-on bias, e_{j,k} a sample path of the axis' :class:`~imunoise.model.Model` (per-sample parameters at
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
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.signal import lfilter

from imunoise.errors import ModelError
from imunoise.imu import AXES, ImuData
from imunoise.io.jsonutil import json_default
from imunoise.io.kfgins import (
    GnssData,
    Reference,
    write_gnss,
    write_imu,
    write_outages,
    write_reference,
)
from imunoise.model import Model
from imunoise.nav.earth import OMEGA_E, radii
from imunoise.sim.imu_errors import models_to_json, resolve_imu_models, simulate_model_errors
from imunoise.sim.law_schedule import LawSchedule, law_schedule
from imunoise.sim.motion import NONE, MotionNoise, modulated_errors, oracle_models, resolve_motion
from imunoise.sim.replay import load_recording, stretch
from imunoise.sim.trajectory import DrivePlan, Kinematics, Ramps, kinematics, simpson_increments

__all__ = ["DriveConfig", "SimulatedDrive", "simulate_drive", "plan_drive"]

_DEG = math.pi / 180.0
SUBSTEPS = 4  # Simpson sub-steps per IMU interval (even)
STATIC_SPEED = 0.05  # m/s: slower than this and without rotation an epoch counts as static


@dataclass
class DriveConfig:
    """Settings of a simulated drive (SI units; angles in degrees where the name says ``_deg``).

    Timing: ``duration_s`` of recording starting with ``static_s`` at rest (alignment), ``n_stops``
    traffic-light stops of ``stop_range_s`` each, and a final stop at the end.
    """

    duration_s: float = 600.0
    n_stops: int = 3
    stop_range_s: tuple[float, float] = (5.0, 90.0)
    static_s: float = 60.0
    imu_rate_hz: float = 100.0
    gnss_rate_hz: float = 1.0
    ref_rate_hz: float | None = 10.0  # None: reference at the IMU rate
    gnss_sigma_m: tuple[float, float, float] = (1.0, 1.0, 2.0)  # N, E, D (reported and simulated)
    outlier_rate: float = 0.0  # fraction of GNSS epochs with a gross error
    outlier_range_m: tuple[float, float] = (10.0, 50.0)  # horizontal size of a gross error
    gnss_noise_tau_s: float = 0.0  # correlation time of the GNSS noise (urban multipath); 0 = white
    outages: list[tuple[float, float]] = field(default_factory=list)  # (start, duration), s from start
    remove_outages: bool = False  # drop GNSS epochs inside the outages from ``gnss`` (``gnss_full`` keeps them)
    start_llh: tuple[float, float, float] = (40.0966, -105.147, 1601.0)  # lat [deg], lon [deg], h [m]
    start_yaw_deg: float | None = None  # None: random
    gps_week: int = 2374
    start_sow: float = 100000.0  # GPS seconds of week at the first sample
    lever_arm_m: tuple[float, float, float] = (0.0, 0.0, 0.0)  # GNSS antenna in body FRD
    seed: int = 0
    # driving style
    cruise_speed_mps: tuple[float, float] = (8.0, 14.0)
    corner_speed_mps: tuple[float, float] = (4.0, 6.0)
    corner_rate_deg_s: tuple[float, float] = (35.0, 50.0)  # peak yaw rate of tight 90° corners
    max_lateral_mps2: float = 4.0
    accel_mps2: float = 1.8
    brake_mps2: float = 2.5
    max_jerk_mps3: float = 3.0
    max_grade_deg: float = 3.0
    roll_gain_deg_per_mps2: float = 0.25  # body roll out of the turn per m/s² lateral acceleration
    # IMU errors other than the stochastic model
    gyro_bias_sigma: float = 200.0 * _DEG / 3600.0  # rad/s, turn-on bias σ (200 °/h)
    accel_bias_sigma: float = 0.05  # m/s², turn-on bias σ (≈5 mg)
    scale_factor_sigma: float = 0.0  # dimensionless σ (1e-3 = 1000 ppm)
    gyro_vibration: float = 0.1 * _DEG  # rad/s std while moving at ≥ 3 m/s (0.1 °/s); only when motion_noise is None
    accel_vibration: float = 0.05  # m/s² std while moving at ≥ 3 m/s; only when motion_noise is None
    # motion law of the stochastic errors (imunoise.sim.motion): a preset ("none", "drive0708") or a
    # MotionNoise; it replaces the vibration term. None: the vibration term alone (the earlier simulator).
    motion_noise: str | MotionNoise | None = None
    # real noise (imunoise.sim.replay): a static recording (.npz) whose stretch [d·n, (d+1)·n), d = seed −
    # imu_noise_first, replaces the stochastic model errors; its last imu_noise_reserve_s s stay unused (the
    # denial experiment's static recording). A law may add its additive terms on top, not scale the recording.
    imu_noise: str | None = None
    imu_noise_first: int = 0
    imu_noise_reserve_s: float = 0.0

    def __post_init__(self) -> None:
        if self.duration_s <= 0 or self.static_s < 0 or self.static_s >= self.duration_s:
            raise ModelError(
                f"need 0 ≤ static_s < duration_s, got static_s={self.static_s}, duration_s={self.duration_s}"
            )
        if self.n_stops < 0:
            raise ModelError(f"n_stops must be ≥ 0, got {self.n_stops}")
        lo, hi = self.stop_range_s
        if not 0 < lo <= hi:
            raise ModelError(f"stop_range_s must be (min, max) with 0 < min ≤ max, got {self.stop_range_s}")
        if not self.imu_rate_hz > 0 or not self.gnss_rate_hz > 0:
            raise ModelError(
                f"imu_rate_hz and gnss_rate_hz must be > 0 Hz, got {self.imu_rate_hz}, {self.gnss_rate_hz}")
        if self.gnss_rate_hz > self.imu_rate_hz:
            raise ModelError(
                f"gnss_rate_hz {self.gnss_rate_hz:g} Hz exceeds imu_rate_hz {self.imu_rate_hz:g} Hz; "
                "GNSS epochs are taken at IMU samples: lower it"
            )
        if not 0.0 <= self.outlier_rate <= 1.0:
            raise ModelError(f"outlier_rate must be in [0, 1], got {self.outlier_rate}")
        if min(self.gnss_sigma_m) <= 0:
            raise ModelError(f"gnss_sigma_m must be > 0, got {self.gnss_sigma_m}")
        self.outages = [(float(s), float(d)) for s, d in self.outages]
        if self.motion_noise is not None:
            law = resolve_motion(self.motion_noise)  # an unknown preset fails here, not after the trajectory
            if self.imu_noise is not None and law.modulates:
                raise ModelError(f"--motion-noise {law.name} scales the white and bias noise of the IMU model; a "
                                 "replayed recording (--imu-noise) is used as it is: give a law with additive "
                                 "terms only (none, gyro_departure_step, gyro_moving_gm, accel_moving_gm, warmup)")
        if self.imu_noise is not None:
            load_recording(self.imu_noise)  # a bad file fails here
        for s, d in self.outages:
            if d <= 0:
                raise ModelError(f"outage ({s}, {d}): the duration (second value, s) must be > 0")

    @classmethod
    def noise_free(cls, **kw: Any) -> DriveConfig:
        """A config without turn-on bias, scale factor, vibration or GNSS outliers."""
        base = dict(
            gyro_bias_sigma=0.0,
            accel_bias_sigma=0.0,
            scale_factor_sigma=0.0,
            gyro_vibration=0.0,
            accel_vibration=0.0,
            outlier_rate=0.0,
        )
        base.update(kw)
        return cls(**base)


# ----------------------------------------------------------------------------------------------
# manoeuvre planning
# ----------------------------------------------------------------------------------------------


def plan_drive(cfg: DriveConfig, rng: np.random.Generator) -> DrivePlan:
    """Script the drive: static start, straights with grade changes, gentle curves, tight 90° corners,
    speed changes, ``n_stops`` traffic-light stops spread over the drive, a final stop. All ramp
    durations are whole IMU intervals so ramp ends fall on the integration grid."""
    dt = 1.0 / cfg.imu_rate_hz
    end = float(cfg.duration_s)

    def q(T: float) -> float:
        return max(1, math.ceil(T / dt - 1e-9)) * dt

    yaw0 = rng.uniform(-math.pi, math.pi) if cfg.start_yaw_deg is None else math.radians(cfg.start_yaw_deg)
    speed, yaw, pitch = Ramps(0.0), Ramps(yaw0), Ramps(0.0)

    def speed_T(v0: float, v1: float, a: float) -> float:
        dv = abs(v1 - v0)
        return q(max(1.875 * dv / a, math.sqrt(5.7735 * dv / cfg.max_jerk_mps3), 0.5))

    def go(t: float, v1: float, a: float) -> float:
        return speed.add(t, speed_T(speed.level, v1, a), v1)

    # stop durations: shrink if they would not leave enough driving time
    n = cfg.n_stops
    lo, hi = cfg.stop_range_s
    durs = rng.uniform(lo, hi, n)
    drive_time = end - cfg.static_s
    per_stop = 25.0  # braking + starting again, s
    reserve = 40.0  # final braking and stand
    budget = drive_time - reserve - n * per_stop - 20.0 * (n + 1)
    if budget < n * lo:
        raise ModelError(
            f"duration {end:g} s is too short for {n} stops of ≥ {lo:g} s after a {cfg.static_s:g} s static "
            f"start; need about {cfg.static_s + reserve + n * (per_stop + lo) + 20.0 * (n + 1):.0f} s"
        )
    if durs.sum() > budget:
        durs = lo + (durs - lo) * (budget - n * lo) / max((durs - lo).sum(), 1e-9)
    durs = np.array([q(d) for d in durs])
    moving = drive_time - reserve - durs.sum()
    due = [cfg.static_s + (i + 1) * moving / (n + 1) + durs[:i].sum() for i in range(n)]

    stops: list[tuple[float, float]] = []
    statics: list[tuple[float, float]] = [(0.0, cfg.static_s)]
    turns: list[dict] = []
    t = float(cfg.static_s)
    cruise = lambda: rng.uniform(*cfg.cruise_speed_mps)  # noqa: E731
    t = go(t, cruise(), cfg.accel_mps2)
    sharp_done = False
    next_stop = 0

    def straight(t: float, T: float) -> float:
        T = q(T)
        if T >= 6.0 and rng.random() < 0.6:  # grade change somewhere in the straight
            Tg = q(rng.uniform(4.0, min(10.0, T - 1.0)))
            t0 = t + q(rng.uniform(0.0, T - Tg))
            if t0 >= pitch.end:
                pitch.add(t0, Tg, math.radians(rng.uniform(-cfg.max_grade_deg, cfg.max_grade_deg)))
        return t + T

    def turn(t: float, angle: float, rate: float, kind: str) -> float:
        T = q(1.875 * abs(angle) / rate)
        turns.append(
            {
                "t0": t,
                "duration": T,
                "angle_deg": math.degrees(angle),
                "peak_rate_deg_s": math.degrees(1.875 * abs(angle) / T),
                "kind": kind,
            }
        )
        return yaw.add(t, T, yaw.level + angle)

    while True:
        v = speed.level
        remaining = end - t
        pending = n - next_stop
        need_final = speed_T(v, 0.0, cfg.brake_mps2) + 5.0
        if pending:
            need_stop = speed_T(v, 0.0, cfg.brake_mps2) + durs[next_stop] + per_stop
            urgent = remaining < need_stop + (pending - 1) * (per_stop + lo) + need_final + 20.0
            if t >= due[next_stop] or urgent:
                t = go(t, 0.0, cfg.brake_mps2)
                stops.append((t, t + durs[next_stop]))
                statics.append(stops[-1])
                t += durs[next_stop]
                next_stop += 1
                if t + per_stop + need_final >= end:
                    break
                t = go(t, cruise(), cfg.accel_mps2)
                continue
        if remaining < need_final + 25.0:
            break
        # a straight, cut short before a due stop
        T = rng.uniform(3.0, 12.0)
        if pending:
            T = min(T, max(due[next_stop] - t, 1.0))
        t = straight(t, T)
        if end - t < need_final + 25.0:
            continue
        r = rng.random()
        if not sharp_done or r < 0.35:  # tight 90° corner at an intersection
            vt = rng.uniform(*cfg.corner_speed_mps)
            rate = math.radians(rng.uniform(*cfg.corner_rate_deg_s))
            vt = min(vt, cfg.max_lateral_mps2 / rate)
            t = go(t, vt, cfg.brake_mps2)
            t = turn(t, rng.choice([-1.0, 1.0]) * math.pi / 2, rate, "corner")
            t = go(t, cruise(), cfg.accel_mps2)
            sharp_done = True
        elif r < 0.65:  # gentle curve at cruise speed
            angle = math.radians(rng.uniform(10.0, 40.0)) * rng.choice([-1.0, 1.0])
            rate = min(cfg.max_lateral_mps2 * 0.5 / max(v, 1.0), math.radians(25.0))
            t = turn(t, angle, rate, "curve")
        elif r < 0.85:  # change of cruise speed
            t = go(t, cruise(), cfg.accel_mps2)
        # else: keep going straight
    if speed.level > 0.0:
        t = go(t, 0.0, cfg.brake_mps2)
    if t > end:
        raise RuntimeError(f"internal planning error: manoeuvres end at {t:.2f} s after the duration {end:g} s")
    statics.append((t, end))
    return DrivePlan(
        duration=end,
        speed=speed,
        yaw=yaw,
        pitch=pitch,
        roll_gain=math.radians(cfg.roll_gain_deg_per_mps2),
        stops=stops,
        static_intervals=statics,
        turns=turns,
    )


# ----------------------------------------------------------------------------------------------
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
        are set), ``truth.json`` and the ``dataset.json`` manifest (SPEC §12; ``ref_point`` says which
        point ``ref`` is)."""
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
    """Simulate an urban drive with known truth (SPEC §10; equations in :mod:`imunoise.sim.trajectory`
    and this module's docstring).

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
        a, b = stretch(rec, seed - cfg.imu_noise_first, n, cfg.imu_rate_hz, reserve_s=cfg.imu_noise_reserve_s)
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

    truth = _truth(cfg, seed, plan, kin, at, models, bias, scale, t[ig][is_out], static_mask, t)
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


def _intervals(mask: np.ndarray, t: np.ndarray) -> list[list[float]]:
    """[t_first, t_last] of each run of True in ``mask``."""
    m = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(m)
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1
    return [[float(t[a]), float(t[b])] for a, b in zip(starts, ends, strict=True)]


def _truth(
    cfg: DriveConfig,
    seed: int,
    plan: DrivePlan,
    kin: Kinematics,
    at: np.ndarray,
    models: dict[str, Model],
    bias: np.ndarray,
    scale: np.ndarray,
    outlier_t: np.ndarray,
    static_mask: np.ndarray,
    t: np.ndarray,
) -> dict[str, Any]:
    s0 = cfg.start_sow
    step = max(1, int(round(cfg.imu_rate_hz)))
    wz = np.degrees(kin.omega_ib_b[at, 2])
    return {
        "seed": seed,
        "units": {
            "time": "GPS seconds of week",
            "gyro": "rad/s (model parameters per sample at imu_rate_hz)",
            "accel": "m/s² (model parameters per sample at imu_rate_hz)",
            "angles": "degrees unless the key says rad",
        },
        "imu_rate_hz": cfg.imu_rate_hz,
        "error_equation": "rate_meas = (1 + scale) * rate_true + turn_on_bias + model_error + vibration; "
        "increment = rate_meas * dt",
        "models": models_to_json(models, cfg.imu_rate_hz),
        "turn_on_bias": {"gyro_rad_s": bias[:3], "accel_m_s2": bias[3:], "axes": list(AXES)},
        "scale_factor": {"gyro": scale[:3], "accel": scale[3:]},
        "vibration_std_at_speed": {
            "gyro_rad_s": cfg.gyro_vibration,
            "accel_m_s2": cfg.accel_vibration,
            "full_at_mps": 3.0,
        },
        "stops": [[s0 + a, s0 + b] for a, b in plan.stops],
        "static_intervals": [[s0 + a, s0 + b] for a, b in plan.static_intervals],
        "static_mask_intervals": _intervals(static_mask, t),
        "turns": [{**tr, "t0": s0 + tr["t0"]} for tr in plan.turns],
        "max_turn_rate_deg_s": float(np.abs(wz).max()),
        "max_speed_mps": float(kin.speed.max()),
        "distance_m": float(np.sum(kin.speed[at]) / cfg.imu_rate_hz),
        "speed_profile": {"t": t[::step], "speed_mps": kin.speed[at][::step]},
        "gnss_outliers_t": outlier_t,
        "outages": [[s0 + s, d] for s, d in cfg.outages],
        "initial_state": {
            "t": float(t[0]),
            "llh_deg_m": [
                math.degrees(kin.llh[at[0], 0]),
                math.degrees(kin.llh[at[0], 1]),
                kin.llh[at[0], 2],
            ],
            "vel_ned_mps": kin.vel[at[0]],
            "euler_deg": np.degrees(kin.euler[at[0]]),
        },
        "config": asdict(cfg),
    }
