"""Fleet modelling on Dask vs a plain sequential loop (issue 6 acceptance 3).

24 simulated static logs (CSV, six axes in deg/s and g, WN+RW per axis) plus one broken file are
modelled with automatic selection, once by :func:`imunoise.batch.run_sequential` and once by
:func:`imunoise.batch.run_batch` on a ``dask.distributed`` LocalCluster (one worker process per core).
The Dask wall time includes the cluster start-up. Both runs must model the 24 logs identically and
report the broken one.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from imunoise.batch import run_batch, run_sequential
from imunoise.noise.model import Model
from imunoise.units import G0

N_FILES = 24
N_SAMPLES = 2**16
FREQ = 200.0
CFG = {
    "freq": FREQ,
    "auto": True,
    "columns": "gyro_x=gx,gyro_y=gy,gyro_z=gz,accel_x=ax,accel_y=ay,accel_z=az",
    "units": {"gyro": "deg/s", "accel": "g"},
}


def make_logs(folder: Path, n_files: int = N_FILES, n: int = N_SAMPLES) -> list[str]:
    """``n_files`` CSV logs (seeded) and one broken file; returns the sorted paths."""
    gyro = Model.parse("WN+RW").with_params({"WN.sigma2": (1.7e-4) ** 2 * FREQ, "RW.gamma2": (2e-5) ** 2 / FREQ})
    accel = Model.parse("WN+RW").with_params({"WN.sigma2": (2e-3) ** 2 * FREQ, "RW.gamma2": (3e-3) ** 2 / FREQ})
    for i in range(n_files):
        g = np.column_stack([np.degrees(gyro.simulate(n, seed=100 * i + k)) for k in range(3)])
        a = np.column_stack([accel.simulate(n, seed=100 * i + 10 + k) / G0 for k in range(3)])
        np.savetxt(folder / f"imu_{i:02d}.csv", np.hstack([g, a]), delimiter=",", fmt="%.9e",
                   header="gx,gy,gz,ax,ay,az", comments="")  # fmt: skip
    (folder / "imu_99_broken.csv").write_text("gx,gy,gz,ax,ay,az\n0,0,0,0,0,0\n1,2,NaN,4,5,6\n")
    return sorted(str(p) for p in folder.glob("*.csv"))


def main() -> str:
    cores = os.cpu_count() or 1
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "logs").mkdir()
        paths = make_logs(tmp / "logs")
        seq = run_sequential(paths, CFG, tmp / "seq")
        par = run_batch(paths, CFG, tmp / "dask", scheduler="local", n_workers=cores, progress=False)
    keys = ("file", "axis", "status", "model", "noise_density", "random_walk_eq")
    same = [tuple(r[k] for k in keys) for r in seq.rows] == [tuple(r[k] for k in keys) for r in par.rows]
    ok = par.n_files - len(par.failed)
    models = sorted({r["model"] for r in par.rows if r["status"] == "ok"})
    ratio = seq.wall_s / par.wall_s
    load_after = os.getloadavg()[0]
    lines = [
        "## Fleet modelling: `imunoise batch` on Dask vs a sequential loop",
        "",
        f"{N_FILES} simulated static logs (CSV, 6 axes × {N_SAMPLES} samples at {FREQ:g} Hz, deg/s and g, "
        f"WN+RW truth) + 1 broken file; `--auto` selection per axis; LocalCluster with {cores} worker "
        "processes (wall time includes cluster start-up).",
        "",
        "| run | wall time (s) | files modelled | failed files reported |",
        "|---|---:|---:|---:|",
        f"| sequential loop | {seq.wall_s:.1f} | {seq.n_files - len(seq.failed)}/{seq.n_files} | {len(seq.failed)} |",
        f"| Dask LocalCluster ({cores} processes) | {par.wall_s:.1f} | {ok}/{par.n_files} | {len(par.failed)} |",
        "",
        f"Speed-up (sequential / Dask): **{ratio:.2f}×** on {cores} cores. Same table from both runs: "
        f"{'yes' if same else 'NO'}. Models selected: {', '.join(models)}. Broken file: "
        f"{', '.join(Path(f).name for f in par.failed) or 'none'} ("
        + "; ".join(r["error"][:80] for r in par.rows if r["status"] != "ok")
        + ").",
        "",
        f"Machine load average (1 min) before / after: {load_before:.1f} / {load_after:.1f} on {cores} cores; "
        "other processes competing for the cores lower the speed-up (ideal: the number of cores, minus the "
        "cluster start-up of a few seconds).",
    ]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(main())
