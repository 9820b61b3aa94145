"""The mounting check on the real drive: data/drive_0708's IMU turned in its mount (the increments rotated by a
fixed roll, pitch, yaw), then `imunoise nav` with and without --mount-rpy; prints the check's angles, the warning
and the horizontal RMS of each run.

    python scripts/imu_mounting.py --rpy 0,0,90 [--nhc] [--outages] [--out out/mounting]

With --sim-seeds A-B it checks simulated 600 s drives instead (SPP-like 1 m GNSS, grades up to 3°, body roll in
turns): the check on each drive as simulated (false alarms) and with the IMU mounted at yaw 90° and at roll 30°
(detections, angle errors); no filter runs.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from imunoise.io.kfgins import read_imu
from imunoise.nav.mounting import mount_matrix, parse_mount_rpy, rotate_imu

REPO = Path(__file__).resolve().parents[1]
DRIVE = REPO / "data" / "drive_0708"


def mounted_copy(folder: Path, rpy: tuple[float, float, float]) -> Path:
    """drive_0708 with its IMU mounted at ``rpy``: each increment x_imu = C_s^vᵀ x_vehicle."""
    folder.mkdir(parents=True, exist_ok=True)
    for f in DRIVE.iterdir():
        if f.name != "imu_body_inc.txt.gz":
            shutil.copy(f, folder / f.name)
    imu = rotate_imu(read_imu(DRIVE / "imu_body_inc.txt.gz"), mount_matrix(rpy).T)
    np.savetxt(folder / "imu_body_inc.txt.gz", np.column_stack([imu.t, imu.dtheta, imu.dv]), fmt="%.15g")
    return folder


def nav(data: Path, out: Path, extra: list[str]) -> dict:
    cmd = [sys.executable, "-m", "imunoise", "nav", "--data", str(data), "--no-plots", "--out", str(out), *extra]
    r = subprocess.run(cmd, capture_output=True, text=True, check=True)
    warn = [ln for ln in r.stderr.splitlines() if "looks mounted" in ln]
    m = json.loads((out / "metrics.json").read_text())
    return {"args": extra, "rms_m": m["horizontal_rms_m"], "warning": warn[0] if warn else None,
            "mounting": m["mounting"]}


def sim_sweep(seeds: range, threshold: float) -> None:
    from imunoise.nav.earth import llh_to_ned
    from imunoise.nav.mounting import estimate_mounting, mounting_warning
    from imunoise.sim.drive import DriveConfig, simulate_drive

    cases = {"as simulated": (0.0, 0.0, 0.0), "yaw 90°": (0.0, 0.0, 90.0), "roll 30°": (30.0, 0.0, 0.0)}
    found: dict[str, list] = {k: [] for k in cases}
    for seed in seeds:
        d = simulate_drive(DriveConfig(duration_s=600.0, seed=seed), "mems", seed=seed)
        g = d.gnss
        ned = llh_to_ned(g.llh, g.llh[0])
        sig = float(np.median(np.hypot(g.sigma_ned[:, 0], g.sigma_ned[:, 1])))
        still = d.imu.t <= d.imu.t[0] + 30.0
        for name, rpy in cases.items():
            imu = rotate_imu(d.imu, mount_matrix(rpy).T)
            e = estimate_mounting(imu.t, imu.dv, still, g.t, ned, sig)
            warned = mounting_warning(e, f"seed {seed}", threshold) is not None
            err = [e.roll_deg - rpy[0], e.pitch_deg - rpy[1], (e.yaw_deg or np.nan) - rpy[2]]
            found[name].append((seed, warned, *err))
            print(f"seed {seed} {name}: warned {warned}; error roll {err[0]:+.2f}° pitch {err[1]:+.2f}° yaw "
                  f"{err[2]:+.2f}° ({e.epochs} epochs)", flush=True)
    for name, rows in found.items():
        a = np.asarray([r[2:] for r in rows], dtype=float)
        n_warn = sum(r[1] for r in rows)
        print(f"{name}: warned on {n_warn}/{len(rows)} drives; |error| max roll {np.nanmax(abs(a[:, 0])):.2f}°, "
              f"pitch {np.nanmax(abs(a[:, 1])):.2f}°, yaw {np.nanmax(abs(a[:, 2])):.2f}° (median yaw "
              f"{np.nanmedian(abs(a[:, 2])):.2f}°; yaw unobserved on {int(np.isnan(a[:, 2]).sum())})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rpy", default="0,0,90", help="the mounting to simulate, roll,pitch,yaw [deg]")
    ap.add_argument("--nhc", action="store_true")
    ap.add_argument("--outages", action="store_true", help="remove the drive's 60 s GNSS outage windows")
    ap.add_argument("--out", default="out/mounting")
    ap.add_argument("--sim-seeds", help="A-B: the simulated sweep over seeds A..B (inclusive) instead")
    ap.add_argument("--threshold", type=float, default=10.0, help="warning threshold [deg]")
    a = ap.parse_args()
    if a.sim_seeds:
        lo, hi = (int(x) for x in a.sim_seeds.split("-"))
        sim_sweep(range(lo, hi + 1), a.threshold)
        return
    rpy = parse_mount_rpy(a.rpy)
    out = Path(a.out)
    data = mounted_copy(out / "data", rpy)
    base = (["--nhc"] if a.nhc else []) + (["--outages", str(DRIVE / "outages_60s.txt")] if a.outages else [])
    runs = [nav(DRIVE, out / "plain", base), nav(data, out / "mounted", base),
            nav(data, out / "corrected", [*base, "--mount-rpy", a.rpy])]
    for name, r in zip(("as recorded", f"mounted {a.rpy}", f"mounted, --mount-rpy {a.rpy}"), runs):
        c = r["mounting"]["check"]
        yaw = "unobserved" if c["yaw_deg"] is None else f"{c['yaw_deg']:.2f}°"
        print(f"{name}: check roll {c['roll_deg']:.2f}° pitch {c['pitch_deg']:.2f}° yaw {yaw}; filter sideslip "
              f"{r['mounting']['filter_sideslip_deg']:.2f}°; horizontal RMS {r['rms_m']:.3f} m")
        print(f"  warning: {r['warning']}")


if __name__ == "__main__":
    main()
