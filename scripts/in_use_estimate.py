"""Recovery of the in-motion noise on simulated drives, and the estimate on the real drive's halves
(docs/evidence/in_use_estimate.md).

    python scripts/in_use_estimate.py sim --laws gyro_moving_gm accel_moving_gm none --seeds 4700 4708 \
        --duration 600 --out out/in_use/dev.json
    python scripts/in_use_estimate.py real --out out/in_use/real.json

``sim``: per law and seed one simulated drive (imunoise.sim), the static part the simulator's true static model
(so the estimate of the in-motion part is measured alone), the estimate (imunoise.inuse.estimate_in_motion),
and per group whether each 95 % interval covers the law's truth (white factor 1; the GM's σ and τ where the law
has one, "none" where it has none: covered when the wander is reported as a bound, i.e. not found).
``real``: data/drive_0708 cut at its middle GNSS epoch; the static part the calibrate fit of each half's stops;
each half estimated alone; CPU seconds per estimate.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from imunoise.imu import AXES
from imunoise.inuse import estimate_in_motion, summary_lines

TRUTH = {  # per law and group: (white factor, σ, τ); σ = 0: no wander
    "gyro_moving_gm": {"gyro": (1.0, 5.817764173314432e-4, 60.0), "accel": (1.0, 0.0, None)},
    "accel_moving_gm": {"gyro": (1.0, 0.0, None), "accel": (1.0, 0.02, 120.0)},
    "none": {"gyro": (1.0, 0.0, None), "accel": (1.0, 0.0, None)},
}


def _true_pairs(sc):
    from imunoise.experiments.common import filter_models
    from imunoise.noise.model import Model
    from imunoise.noise.processes import WN
    from imunoise.online import OnlineConfig

    none = Model([WN(sigma2=1e-30)])
    cfg = OnlineConfig().with_(ekf=sc.ekf_config(), floor="none")
    return filter_models([sc.extra["static_models"].get(ax, none) for ax in AXES], sc.rate, cfg)


def _coverage(part, law: str) -> dict:
    out = {}
    for g, axis in (("gyro", "gyro_x"), ("accel", "accel_x")):
        ax = part.axes[axis]
        f, s, tau = TRUTH.get(law, {}).get(g, (None, None, None))
        row = {"white": ax.white_factor.to_dict(), "bias": ax.bias.to_dict(),
               "bound": part.bounds[axis].to_dict() if axis in part.bounds else None}
        if f is not None:
            row["white_covers"] = ax.white_factor.covers(f) if ax.white_factor.value is not None else None
            if s == 0:
                row["bias_covers"] = ax.bias.model == "none"
            elif ax.bias.model == "gm":
                ci = ax.bias.ci95
                row["sigma_covers"] = bool(ci["sigma"][0] <= s <= ci["sigma"][1])
                row["tau_covers"] = bool(ci["tau_s"][0] <= tau <= ci["tau_s"][1])
            elif ax.bias.model == "rw":  # τ not identified: the driving density against the GM's
                ci = ax.bias.ci95["k"]
                row["k_covers"] = bool(ci[0] <= math.sqrt(2.0 * s * s / tau) <= ci[1])
            else:
                row["sigma_covers"] = row["tau_covers"] = False
        out[g] = row
    return out


def run_sim(args) -> list:
    from imunoise.experiments.common import simulate_scenario

    rows = []
    for law in args.laws:
        for seed in range(args.seeds[0], args.seeds[1]):
            sc = simulate_scenario(seed, duration_s=args.duration, motion_noise=law, n_outages=0,
                                   n_stops=args.stops)
            t0 = time.process_time()
            est = estimate_in_motion([sc], _true_pairs(sc), freq=sc.rate, names=[sc.name])
            row = {"law": law, "seed": seed, "cpu_s": time.process_time() - t0, "runs": est.runs,
                   "lr_wander": est.lr_wander, **_coverage(est.part, law)}
            rows.append(row)
            print(f"{law} {seed}: {row['cpu_s']:.1f} s CPU, {est.runs} runs", *summary_lines(est.part)[::3],
                  sep="\n  ", flush=True)
    return rows


def _half(sc, lo: float, hi: float, name: str):
    """The drive cut at ``hi`` whose likelihood scores only the fixes from ``lo`` on: the filter runs from the
    drive's own alignment (a stop), so the second half starts from a converged state; the in-motion noise
    applies over the whole run, the fixes of the other half are not scored."""
    from dataclasses import replace

    imu = sc.imu.slice(float(sc.imu.t[0]), hi)
    m = np.asarray(sc.imu.t) <= hi
    st = None if sc.static_truth is None else np.asarray(sc.static_truth)[m]
    return replace(sc, name=name, imu=imu, gnss=sc.gnss.slice(float(sc.gnss.t[0]), hi), static_truth=st,
                   extra={**sc.extra, "score_after_s": lo})


def run_real(args) -> list:
    from imunoise.experiments.common import load_real, repo_data_dir
    from imunoise.inuse.estimate import static_models

    sc = load_real(repo_data_dir())
    model = args.static_model
    t0g, t1g = float(sc.init.t), float(np.asarray(sc.gnss.t)[-1])
    mid = 0.5 * (t0g + t1g)
    rows = []
    for name, (lo, hi) in (("first half", (t0g, mid)), ("second half", (mid, t1g + 1.0)), ("whole", (t0g, t1g + 1))):
        d = _half(sc, lo, hi, f"drive_0708 {name}")
        t0 = time.process_time()
        est = estimate_in_motion([d], static_models(json.loads(Path(model).read_text()), sc.rate), freq=sc.rate,
                                 names=[d.name])
        cpu = time.process_time() - t0
        rows.append({"half": name, "span_s": [lo, hi], "cpu_s": cpu, "runs": est.runs, "part": est.part.to_dict(),
                     "lr_wander": est.lr_wander})
        print(name, f"{cpu:.1f} s CPU, {est.runs} filter runs", *summary_lines(est.part), sep="\n  ", flush=True)
    return rows


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="what", required=True)
    s = sub.add_parser("sim")
    s.add_argument("--laws", nargs="+", default=["gyro_moving_gm", "accel_moving_gm", "none"])
    s.add_argument("--seeds", nargs=2, type=int, default=[4700, 4708], help="first, end (exclusive)")
    s.add_argument("--duration", type=float, default=600.0, help="drive length [s]")
    s.add_argument("--stops", type=int, default=4)
    s.add_argument("--out", required=True)
    r = sub.add_parser("real")
    r.add_argument("--static-model", required=True, help="model.json of calibrate on the drive's stops")
    r.add_argument("--out", required=True)
    args = p.parse_args(argv)
    rows = run_sim(args) if args.what == "sim" else run_real(args)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps({"argv": sys.argv, "rows": rows}, indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
