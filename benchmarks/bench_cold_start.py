"""Cold start of the online engine (issue "Evidence with power" §3, acceptance 4): the first identification
per axis in a fresh process, with numba's on-disk cache empty (a fresh clone) and filled, with and without
the warm-up at construction (:func:`imunoise.warm_up`).

Every run is a fresh ``python -c`` that replays the first 30 s of data/drive_0708 (up to the first
identification) through :class:`imunoise.online.OnlineNavigator` (inline worker) and reports the
``identified`` event's per-axis ``time_s``, the ``warm_up`` event, and the same identification job run a
second time in that process (steady state). ``NUMBA_CACHE_DIR`` points at a temporary directory, so the
empty-cache runs do not touch the checkout's cache. Baseline of the same run: ``python -c "import numpy"``.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

from imunoise.experiments.common import repo_data_dir

SRC = Path(__file__).resolve().parents[1] / "src"

PROBE = textwrap.dedent(
    """
    import json, sys, time
    t_start = time.perf_counter()
    import numpy as np
    import imunoise.online as online
    from imunoise.io.dataset import read_dataset
    from imunoise.io.kfgins import read_gnss, read_imu
    from imunoise.nav.align import coarse_align

    again = []
    cpu = []
    import imunoise.online.modeller as home  # where the online engine calls the modelling job
    name = "model_job"
    job = getattr(home, name)

    def timed(kind, *args, **kw):
        c0 = time.process_time()
        out = job(kind, *args, **kw)
        if kind == "identify" and not again:
            c1 = time.process_time()
            again.append(job(kind, *args, **kw)["elapsed"])  # the same job once more: steady state
            cpu.extend([c1 - c0, time.process_time() - c1])
        return out

    setattr(home, name, timed)
    ds = read_dataset(sys.argv[1])
    imu = read_imu(ds.imu, time_offset=ds.imu_time_offset_s)
    gnss = read_gnss(ds.gnss)
    t0 = float(ds.extra["start_sow"])
    init = coarse_align(imu, gnss, t0, static_duration=30.0, lever_arm=np.asarray(ds.lever_arm_m, dtype=float))
    imu, gnss = imu.slice(imu.t[0], t0 + 30.0), gnss.slice(gnss.t[0], t0 + 30.0)
    cfg = online.OnlineConfig(warm_up=sys.argv[2] == "1", store=False)
    nav = online.OnlineNavigator(cfg, init, imu_rate_hz=float(imu.rate_hz))
    res = nav.run(imu, gnss)
    ident = next(e for e in res.events if e["event"] == "identified")
    warm = next((e for e in res.events if e["event"] == "warm_up"), None)
    axes = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")
    print(json.dumps({"first": [ident["axes"][a]["time_s"] for a in axes], "steady": again[0], "cpu": cpu,
                      "warm_up": warm, "process_s": time.perf_counter() - t_start}))
    """
)


def _probe(cache_dir: str, warm: bool) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(SRC) + os.pathsep + env.get("PYTHONPATH", "")
    env["NUMBA_CACHE_DIR"] = cache_dir
    out = subprocess.run([sys.executable, "-c", PROBE, str(repo_data_dir()), "1" if warm else "0"],
                         capture_output=True, text=True, env=env, timeout=900)
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-3000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def _baseline() -> float:
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c", "import numpy"], check=True)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def measure() -> dict:
    """The four fresh-process cases and the baseline (seconds)."""
    base = _baseline()
    runs = {}
    for warm in (False, True):
        with tempfile.TemporaryDirectory(prefix="imunoise-numba-") as cache:
            runs[("empty", warm)] = _probe(cache, warm)  # fills the cache ...
            runs[("filled", warm)] = _probe(cache, warm)  # ... which the next fresh process loads
    return {"baseline_s": base, "runs": runs}


def main() -> str:
    m = measure()
    base = m["baseline_s"]
    lines = [
        "## Cold start of the online engine (`imunoise.warm_up`)",
        "",
        "Fresh `python -c` processes replaying the first 30 s of `data/drive_0708` (up to the first "
        "identification, 21 s of static data, inline worker). *First identification*: the `identified` "
        "event's per-axis `time_s` (wall clock); *steady*: the same job run again in that process; *CPU*: "
        "process CPU time of the whole six-axis job, first and steady (robust against other load on the "
        "machine). numba's cache "
        "directory (`NUMBA_CACHE_DIR`) is a new empty directory for the *empty* runs and the one they filled "
        f"for the *filled* runs. Baseline of this run: `python -c \"import numpy\"` = {base:.3f} s.",
        "",
        "| numba cache | warm-up at construction | warm-up wall [s] (compiled / loaded) | first identification per "
        "axis, wall [s] | slowest axis, wall [s] | worst axis first ÷ steady | slowest ÷ baseline "
        "| CPU first / steady job [s] "
        "| process wall [s] |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for (cache, warm), r in m["runs"].items():
        w = r["warm_up"]
        wtxt = f"{w['time_s']:.2f} ({w['compiled']} / {w['loaded']})" if w else "—"
        first = r["first"]
        slow = max(first)
        lines.append(
            f"| {cache} | {'yes' if warm else 'no'} | {wtxt} | " + ", ".join(f"{x:.2f}" for x in first)
            + f" | {slow:.2f} | {max(f / q for f, q in zip(first, r['steady'])):.1f}× | {slow / base:.1f}× "
            f"| {r['cpu'][0]:.2f} / {r['cpu'][1]:.2f} | {r['process_s']:.1f} |"
        )
    lines += [
        "",
        "Target (issue \"Evidence with power\", acceptance 4): first identification ≤ 1 s per axis in a fresh "
        "process. Without the warm-up, the first axis of the first identification paid for compiling (empty "
        "cache) or loading (filled cache) the fitting kernels; with it, that cost is the `warm_up` event at "
        "construction. Precompile every command's kernels after an install: `imunoise warm-up`.",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    print(main())
