"""Manoeuvre planning of a simulated drive (docs/guide/theory.rst, 'Simulator'): the scripted speed, yaw and pitch
profiles, stops and turns, on the IMU integration grid."""

from __future__ import annotations

import math

import numpy as np

from imunoise.errors import ModelError
from imunoise.sim.drive_config import DriveConfig
from imunoise.sim.trajectory import DrivePlan, Ramps

__all__ = ["plan_drive"]


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

