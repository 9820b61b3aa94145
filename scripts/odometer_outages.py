"""Wheel odometer through GNSS outages on the simulator: odometer + NHC against NHC alone, paired per drive.

Each seed is one simulated 600 s urban drive (imunoise.experiments.common.simulate_scenario: the mems IMU under the
drive0708 motion law, four stops, four 60 s GNSS outages at least 60 s into the drive, all in one run) with its
odometer simulated from the truth (imunoise.nav.aiding_sources: the IMU point's forward speed at 10 Hz times
(1 + ε), ε ~ N(0, 0.5 %) once per drive, plus 5 cm/s white noise). The batch filter (what `imunoise nav --nhc
--odometer` runs) navigates each drive four times: plain, odometer alone, NHC alone, odometer + NHC, with the
filter's defaults (odometer σ 5 cm/s, scale-factor σ 1 % of the speed in R).

The metric is the horizontal error at the end of each outage [m]. A drive is one cluster: its four windows share
the IMU's errors, so the per-drive log ratio is the mean over its windows of log(end error with / without), and the
95 % CI of the geometric-mean ratio is the Student-t interval of those per-drive values over the drives.

    python scripts/odometer_outages.py --seeds 4400 4449 --role dev --out out/odometer_dev.json
    python scripts/odometer_outages.py --seeds 6520000 6520019 --role report --out out/odometer_report.json
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np
from scipy import stats

from imunoise.experiments.common import simulate_scenario
from imunoise.nav.ekf import run_ekf
from imunoise.nav.measurements.nhc import NhcConfig
from imunoise.nav.metrics import nav_errors

CONFIGS = ("plain", "odometer", "nhc", "nhc+odometer")
PAIRS = (("nhc+odometer", "nhc"), ("odometer", "plain"))


def drive(seed: int) -> dict:
    """End-of-outage horizontal errors [m] of every configuration on the drive of ``seed``."""
    sc = simulate_scenario(seed, duration_s=600.0, n_stops=4, n_outages=4, outage_s=60.0, streams=("odometer",))
    gnss = sc.gnss.without(sc.windows)
    base = sc.ekf_config()
    out = {"seed": seed, "windows": [list(w) for w in sc.windows], "odometer_source": sc.extra["streams"][0].source}
    for name in CONFIGS:
        cfg = base.with_(aiding=(NhcConfig(),)) if "nhc" in name else base
        r = run_ekf(sc.imu, gnss, sc.init, cfg, streams=sc.extra["streams"] if "odometer" in name else ())
        err = nav_errors(r.t, r.llh, r.vel_ned, r.euler, sc.ref)
        out[name] = [float(err.horizontal[np.searchsorted(err.t, s + length) - 1]) for s, length in sc.windows]
    return out


def paired(drives: list[dict], a: str, b: str) -> dict:
    """Geometric-mean ratio a/b of the end errors with its 95 % CI over drives (module docstring)."""
    d = np.array([np.mean(np.log(np.asarray(x[a]) / np.asarray(x[b]))) for x in drives])
    n = d.size
    m, se = float(d.mean()), float(d.std(ddof=1) / math.sqrt(n))
    tq = float(stats.t.ppf(0.975, n - 1))
    lo, hi = math.exp(m - tq * se), math.exp(m + tq * se)
    return {"method": a, "baseline": b, "ratio": math.exp(m), "ci95": [lo, hi], "n_drives": n,
            "n_windows": int(sum(len(x[a]) for x in drives)), "better_drives": int(np.sum(d < 0)),
            "mean_end_m": {a: float(np.mean([np.mean(x[a]) for x in drives])),
                           b: float(np.mean([np.mean(x[b]) for x in drives]))},
            "verdict": "lower" if hi < 1 else ("higher" if lo > 1 else "not significant")}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, nargs=2, required=True, metavar=("FIRST", "LAST"), help="seed range, inclusive")
    p.add_argument("--role", choices=("dev", "report"), required=True)
    p.add_argument("--out", required=True, help="results JSON")
    a = p.parse_args(argv)
    t0 = time.perf_counter()
    drives = []
    for s in range(a.seeds[0], a.seeds[1] + 1):
        drives.append(drive(s))
        print(f"seed {s}: " + ", ".join(f"{c} {np.mean(drives[-1][c]):.1f} m" for c in CONFIGS), file=sys.stderr)
    res = {"role": a.role, "seeds": list(a.seeds), "drives": drives, "paired": [paired(drives, x, y) for x, y in PAIRS],
           "elapsed_s": time.perf_counter() - t0}
    with open(a.out, "w") as fh:
        json.dump(res, fh, indent=1)
    for r in res["paired"]:
        lo, hi = r["ci95"]
        print(f"{r['method']} / {r['baseline']}: ratio {r['ratio']:.3f} (95 % CI {lo:.3f}–{hi:.3f}), "
              f"{r['n_drives']} drives, {r['n_windows']} windows, lower on {r['better_drives']} drives; mean end "
              f"{r['mean_end_m'][r['method']]:.1f} m vs {r['mean_end_m'][r['baseline']]:.1f} m: {r['verdict']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
