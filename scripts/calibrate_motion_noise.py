"""Calibration of the motion-noise preset against the real drive (imunoise.sim.motion).

Per gyro axis: the ratio (std of 10 s means of the true gyro error while moving) / (static ADEV at 10 s) on
simulated drives of the experiments' default scenario (600 s, 4 stops, paper IMU preset), for the motion
law ``none`` and the preset, next to the real drive's ratio (data/drive_0708: 58/64, 144/37, 123/6).

10 s means: consecutive 10 s blocks inside each moving run (static mask off), the block means of the
drive's stochastic error path pooled over the drive, their std (ddof 1); per law the root mean square of
that std over the seeds. Static ADEV at 10 s: √(2 ν²(τ)) of the true static model (Haar WV ν² = AVAR/2).

    PYTHONPATH=src python scripts/calibrate_motion_noise.py [--seeds 20] [--imu paper] [--motion drive0708]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from imunoise.imu import GYRO_AXES
from imunoise.sim import DriveConfig, simulate_drive
from imunoise.sim.motion import DEFAULT_MOTION, REAL_DRIVE_GYRO

DPH = math.pi / 180.0 / 3600.0  # °/h in rad/s


def moving_block_std(err: np.ndarray, moving: np.ndarray, rate_hz: float, block_s: float = 10.0) -> np.ndarray:
    """Std (ddof 1) of the ``block_s`` means of ``err`` (n, k) over whole blocks inside runs of ``moving``."""
    size = int(round(block_s * rate_hz))
    edges = np.diff(np.concatenate([[0], moving.astype(np.int8), [0]]))
    means = []
    for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True):
        k = (b - a) // size
        if k:
            means.append(err[a:a + k * size].reshape(k, size, -1).mean(axis=1))
    return np.concatenate(means).std(axis=0, ddof=1)


def drive_ratios(seed: int, imu: str, motion: str, duration_s: float = 600.0, n_stops: int = 4) -> np.ndarray:
    """(std of 10 s means while moving, static ADEV at 10 s) per gyro axis [°/h], shape (2, 3)."""
    cfg = DriveConfig(duration_s=duration_s, n_stops=n_stops, seed=seed, motion_noise=motion)
    d = simulate_drive(cfg, imu, seed=seed)
    rate = cfg.imu_rate_hz
    moving = moving_block_std(d.model_errors[:, :3], ~d.static_mask, rate) / DPH
    adev = [math.sqrt(2.0 * float(d.imu_models[ax].wv(np.array([10.0 * rate]))[0])) / DPH for ax in GYRO_AXES]
    return np.array([moving, adev])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--imu", default="paper")
    ap.add_argument("--motion", default=DEFAULT_MOTION)
    args = ap.parse_args()
    real = np.array(REAL_DRIVE_GYRO["moving_std_10s_dph"]) / np.array(REAL_DRIVE_GYRO["static_adev_10s_dph"])
    print(f"IMU preset {args.imu}, {args.seeds} drives of 600 s with 4 stops; gyro x / y / z")
    print(f"{'':<22}{'moving std 10 s [°/h]':>26}{'static ADEV 10 s [°/h]':>26}{'ratio':>22}")
    for law in ("none", args.motion):
        r = np.array([drive_ratios(s, args.imu, law) for s in range(args.seeds)])
        moving = np.sqrt(np.mean(r[:, 0] ** 2, axis=0))
        adev = r[0, 1]
        print(f"{'sim, motion ' + law:<22}{_row(moving):>26}{_row(adev):>26}{_row(moving / adev, 2):>22}")
    print(f"{'real drive_0708':<22}{_row(REAL_DRIVE_GYRO['moving_std_10s_dph']):>26}"
          f"{_row(REAL_DRIVE_GYRO['static_adev_10s_dph']):>26}{_row(real, 2):>22}")


def _row(v, nd: int = 0) -> str:
    return " / ".join(f"{x:.{nd}f}" for x in v)


if __name__ == "__main__":
    main()
