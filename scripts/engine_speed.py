"""Speed of the filter engine against another source tree, in the same run, on two clocks.

CPU time (``--clock cpu``, the default): the batch filter on the shipped drive (data/drive_0708, 548 s, NHC on) and
the online engine without modelling on the same drive (detector + filter in spans), each timed in a fresh process
per round, rounds alternating between the two trees; the median over rounds of each process's best, and the
ratio new/old with a 95 % bootstrap interval over the rounds.

Instructions (``--clock instructions``): the instructions executed by the same batch call on the first
``--seconds`` of the drive, counted by ``valgrind --tool=callgrind`` between two client requests around the call
(a 5-line helper compiled with ``cc`` against valgrind's ``callgrind.h``); repeatable to about 1e-6 whatever the
machine's load. valgrind does not run AVX-512, so both trees compile their kernels for ``haswell``
(``NUMBA_CPU_NAME``) in this mode, natively first to fill numba's cache, then under valgrind.

``python scripts/engine_speed.py OLD_SRC NEW_SRC [--rounds 5] [--clock cpu|instructions]`` prints the numbers of
each and new/old. The trees are ``src`` folders (``git archive <commit> src | tar -x -C DIR``).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

CHILD = r"""
import json, time, sys
import numpy as np
from imunoise.experiments.common import load_real
from imunoise.nav.ekf import run_ekf
from imunoise.nav.measurements.nhc import NhcConfig
from imunoise.online import OnlineConfig, OnlineNavigator
from dataclasses import replace
sc = load_real(sys.argv[1])
cfg = replace(sc.ekf_config(), aiding=(NhcConfig(),))
run_ekf(sc.imu, sc.gnss, sc.init, cfg)  # warm (kernels load from the cache)
ts = []
for _ in range(3):
    t0 = time.process_time(); run_ekf(sc.imu, sc.gnss, sc.init, cfg); ts.append(time.process_time() - t0)
base = OnlineConfig(ekf=sc.ekf_config(), latency=0.5, modelling=False)
OnlineNavigator(base, sc.init, imu_rate_hz=sc.rate).run(sc.imu, sc.gnss)
to = []
for _ in range(2):
    nav = OnlineNavigator(base, sc.init, imu_rate_hz=sc.rate)
    t0 = time.process_time(); nav.run(sc.imu, sc.gnss); to.append(time.process_time() - t0)
print(json.dumps({"batch": min(ts), "online": min(to)}))
"""


COUNTED = r"""
import ctypes, pickle, sys
from dataclasses import replace
from imunoise.experiments.common import load_real
from imunoise.nav.ekf import run_ekf
from imunoise.nav.measurements.nhc import NhcConfig
sc = load_real(sys.argv[1])
cfg = replace(sc.ekf_config(), aiding=(NhcConfig(),))
t_end = sc.init.t + float(sys.argv[2])
run_ekf(sc.imu, sc.gnss, sc.init, cfg, t_end=t_end)  # loads (or compiles) the kernels
if len(sys.argv) > 3:
    import gc
    mark = ctypes.CDLL(sys.argv[3]).cg_toggle
    gc.collect()
    gc.disable()  # a collection inside the counted call would count the heap's history, not the filter
    mark()
    run_ekf(sc.imu, sc.gnss, sc.init, cfg, t_end=t_end)
    mark()
"""

MARKER = "#include <valgrind/callgrind.h>\nvoid cg_toggle(void) { CALLGRIND_TOGGLE_COLLECT; }\n"


def one(src: str) -> dict:
    env = dict(os.environ, PYTHONPATH=src)
    out = subprocess.run([sys.executable, "-c", CHILD, str(REPO / "data" / "drive_0708")], env=env, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def counted(src: str, seconds: float, lib: str) -> int:
    """Instructions of one batch call on the first ``seconds`` of the drive (module docstring)."""
    env = dict(os.environ, PYTHONPATH=src, PYTHONHASHSEED="0", NUMBA_CPU_NAME="haswell", NUMBA_CPU_FEATURES="")
    args = [sys.executable, "-c", COUNTED, str(REPO / "data" / "drive_0708"), str(seconds)]
    subprocess.run(args, env=env, check=True, capture_output=True)  # fills the haswell cache natively
    with tempfile.TemporaryDirectory() as tmp:
        r = subprocess.run(["valgrind", "--tool=callgrind", "--collect-atstart=no",
                            f"--callgrind-out-file={tmp}/cg.out", *args, lib], env=env, check=True,
                           capture_output=True, text=True)
    return int(re.findall(r"Collected : (\d+)", r.stderr)[-1])


def ratio_ci(old: list[float], new: list[float], seed: int = 0) -> tuple[float, float, float]:
    """Ratio of the medians new/old and its 95 % bootstrap interval over the rounds."""
    rng = np.random.default_rng(seed)
    o, n = np.asarray(old), np.asarray(new)
    boot = [np.median(rng.choice(n, n.size)) / np.median(rng.choice(o, o.size)) for _ in range(2000)]
    return float(np.median(n) / np.median(o)), *np.percentile(boot, [2.5, 97.5])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("old")
    p.add_argument("new")
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--clock", choices=("cpu", "instructions"), default="cpu")
    p.add_argument("--seconds", type=float, default=100.0, help="drive length of the instruction count [s]")
    a = p.parse_args()
    if a.clock == "instructions":
        with tempfile.TemporaryDirectory() as tmp:
            (Path(tmp) / "marker.c").write_text(MARKER)
            lib = str(Path(tmp) / "libcgmark.so")
            subprocess.run(["cc", "-O2", "-shared", "-fPIC", "-o", lib, str(Path(tmp) / "marker.c")], check=True)
            o, n = counted(a.old, a.seconds, lib), counted(a.new, a.seconds, lib)
        print(f"batch {a.seconds:.0f} s  old {o} instructions  new {n} instructions  new/old {n / o:.4f}")
        return
    res: dict[str, list[dict]] = {"old": [], "new": []}
    for r in range(a.rounds):
        for name in (("old", "new") if r % 2 == 0 else ("new", "old")):
            res[name].append(one(getattr(a, name)))
    for key in ("batch", "online"):
        o = [x[key] for x in res["old"]]
        n = [x[key] for x in res["new"]]
        q, lo, hi = ratio_ci(o, n)
        print(f"{key:6s}  old {statistics.median(o):.3f} s CPU  new {statistics.median(n):.3f} s CPU  new/old "
              f"{q:.3f} (95 % CI {lo:.3f}–{hi:.3f}; {a.rounds} rounds, median)")


if __name__ == "__main__":
    main()
