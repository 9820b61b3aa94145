"""Configuration of a simulated drive (docs/guide/theory.rst, 'Simulator'): duration, rates, route, stops, GNSS, sensor
errors and the motion-dependent noise law."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from imunoise.errors import ModelError
from imunoise.sim.motion import MotionNoise, resolve_motion
from imunoise.sim.replay import load_recording, stretch_index

__all__ = ["DriveConfig"]

_DEG = math.pi / 180.0


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
    # Vehicles of imu_noise_drives drives (--vehicle-drives): vehicle seed − imu_noise_first takes that many
    # consecutive stretches, this drive the one imu_noise_earlier drives before the scored drive
    # (imunoise.sim.replay.stretch_index).
    imu_noise: str | None = None
    imu_noise_first: int = 0
    imu_noise_reserve_s: float = 0.0
    imu_noise_drives: int = 1
    imu_noise_earlier: int = 0

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
            stretch_index(0, self.imu_noise_earlier, self.imu_noise_drives)  # so does a drive without a stretch
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
