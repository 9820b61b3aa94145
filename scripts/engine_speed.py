"""Speed of the filter engine against another source tree, in the same run: the batch filter on the shipped
drive (data/drive_0708, 548 s, NHC on) and the online engine without modelling on the same drive (detector +
filter in spans), each timed in a fresh process per round, rounds alternating between the two trees.

``python scripts/engine_speed.py OLD_SRC NEW_SRC [--rounds 5]`` prints the median CPU seconds of each and the
ratio new/old. The trees are ``src`` folders (``git archive <commit> src | tar -x -C DIR``).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

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


def one(src: str) -> dict:
    env = dict(os.environ, PYTHONPATH=src)
    out = subprocess.run([sys.executable, "-c", CHILD, str(REPO / "data" / "drive_0708")], env=env, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("old")
    p.add_argument("new")
    p.add_argument("--rounds", type=int, default=5)
    a = p.parse_args()
    res: dict[str, list[dict]] = {"old": [], "new": []}
    for r in range(a.rounds):
        for name in (("old", "new") if r % 2 == 0 else ("new", "old")):
            res[name].append(one(getattr(a, name)))
    for key in ("batch", "online"):
        o = statistics.median(x[key] for x in res["old"])
        n = statistics.median(x[key] for x in res["new"])
        print(f"{key:6s}  old {o:.3f} s CPU  new {n:.3f} s CPU  new/old {n / o:.3f}  ({a.rounds} rounds, median)")


if __name__ == "__main__":
    main()
