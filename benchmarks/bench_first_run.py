"""First run after an install (issue "Performance where users wait", acceptance 1): `imunoise nav --no-plots`
on the bundled drive in a fresh process with numba's cache empty, the same command once the cache is warm,
and `imunoise warm-up` itself, with the compile CPU time of every kernel.

Every run is a fresh process whose ``NUMBA_CACHE_DIR`` is a new temporary directory (so the checkout's own
cache is neither used nor touched). CPU = user + system time of that process (``os.wait4``), robust against
the other load of a shared machine; wall is reported beside it.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DRIVE = REPO / "data" / "drive_0708"
WARM_REPS = 3


# `python -m imunoise ARGS` that also writes its own peak RSS (VmHWM, kB) to $IMUNOISE_HWM at exit: the
# rusage of a child (wait4) would report the parent's peak instead, which a fork carries over on Linux
HWM_WRAPPER = """
import atexit, os, runpy, sys
def _hwm():
    with open("/proc/self/status") as f:
        kb = next(line.split()[1] for line in f if line.startswith("VmHWM:"))
    with open(os.environ["IMUNOISE_HWM"], "w") as f:
        f.write(kb)
atexit.register(_hwm)
sys.argv = ["imunoise", *sys.argv[1:]]
runpy.run_module("imunoise", run_name="__main__", alter_sys=True)
"""


def _run(argv: list[str], cache: str) -> dict:
    """Wall, CPU [s], peak RSS [MiB], stdout and stderr of one fresh `python -m imunoise ARGV` process."""
    hwm = Path(tempfile.mkdtemp()) / "hwm"
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, IMUNOISE_HWM=str(hwm),
               PYTHONPATH=str(REPO / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""))
    argv = [sys.executable, "-c", HWM_WRAPPER, *argv]
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(argv, env=env, stdout=out, stderr=err)
        _, status, ru = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        so, se = out.read().decode(), err.read().decode()
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(argv)} exited {proc.returncode}: {se[-2000:]}")
    rss = int(hwm.read_text()) / 1024
    hwm.unlink()
    hwm.parent.rmdir()
    return {"wall": wall, "cpu": ru.ru_utime + ru.ru_stime, "rss": rss, "out": so, "err": se}


def measure() -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        nav = ["nav", "--data", str(DRIVE), "--no-plots", "--out", str(Path(tmp) / "nav")]
        cold_dir, warm_dir = str(Path(tmp) / "cache_cold"), str(Path(tmp) / "cache_warm")
        cold = _run(nav, cold_dir)  # an empty cache: compiles, then writes the cache
        again = [_run(nav, cold_dir) for _ in range(WARM_REPS)]  # the cache that first run filled
        warmup = _run(["warm-up", "--timings"], warm_dir)
        after = [_run(nav, warm_dir) for _ in range(WARM_REPS)]  # after `imunoise warm-up` only
    return {"cold": cold, "again": again, "warmup": warmup, "after": after}


def _med(runs: list[dict], key: str) -> float:
    return statistics.median(r[key] for r in runs)


def main() -> str:
    lines = ["## First run after an install (`imunoise warm-up`)", ""]
    if not (DRIVE / "dataset.json").exists():
        return "\n".join(lines + [f"({DRIVE} not found: skipped)"])
    m = measure()
    cold, again, after, wu = m["cold"], m["again"], m["after"], m["warmup"]
    notice = [ln for ln in cold["err"].splitlines() if "compiling kernels" in ln]
    quiet = all("compiling kernels" not in r["err"] for r in again + after)
    table = [ln for ln in wu["out"].splitlines() if ln.startswith("|")]
    summary = next((ln for ln in wu["out"].splitlines() if ln.startswith("done in")), "")
    lines += [
        "`imunoise nav --data data/drive_0708 --no-plots` (548 s drive) in fresh processes, each with its own "
        "`NUMBA_CACHE_DIR`. CPU = user + system time of the process; warm rows: median of "
        f"{WARM_REPS}.",
        "",
        "| run | CPU [s] | wall [s] | peak RSS [MiB] |",
        "|---|---:|---:|---:|",
        f"| empty cache (first run after an install) | {cold['cpu']:.2f} | {cold['wall']:.2f} | {cold['rss']:.0f} |",
        f"| cache filled by that first run | {_med(again, 'cpu'):.2f} | {_med(again, 'wall'):.2f} "
        f"| {_med(again, 'rss'):.0f} |",
        f"| after `imunoise warm-up` (its own cache) | {_med(after, 'cpu'):.2f} | {_med(after, 'wall'):.2f} "
        f"| {_med(after, 'rss'):.0f} |",
        f"| `imunoise warm-up`, empty cache | {wu['cpu']:.1f} | {wu['wall']:.1f} | {wu['rss']:.0f} |",
        "",
        f"First run ÷ warm run (CPU): **{cold['cpu'] / _med(after, 'cpu'):.1f}×**. Target (acceptance 1): the "
        f"first `nav --no-plots` after `imunoise warm-up` ≤ 3 s — measured {_med(after, 'wall'):.2f} s wall "
        f"({'meets' if _med(after, 'wall') <= 3.0 else 'misses'}). The empty-cache run printed "
        f"{len(notice)} notice line(s) on stderr" + (f": `` {notice[0]} ``" if notice else "")
        + f"; the warm runs printed {'none' if quiet else 'one (unexpected)'}.",
        "",
        f"`imunoise warm-up --timings` with an empty cache: {summary.removeprefix('done in ').strip()}. "
        "Compile CPU per kernel (self time: a kernel's callees compiled while it is typed are charged to "
        "themselves; a kernel compiled for several signatures is summed):",
        "",
        *table,
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    print(main())
