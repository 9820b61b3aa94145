"""Recovery of the in-motion noise on simulated drives, and the estimate on the real drive's halves
(docs/evidence/in_use_estimate.md).

    python scripts/in_use_estimate.py sim --laws gyro_moving_gm accel_moving_gm none --seeds 4700 4708 \
        --duration 600 --workers 2 --out out/in_use/dev.json
    python scripts/in_use_estimate.py real --out out/in_use/real.json

``sim``: per law and seed one simulated drive (imunoise.sim), the static part the simulator's true static model
(so the estimate of the in-motion part is measured alone), the estimate (imunoise.inuse.estimate_in_motion),
and per group whether each 95 % interval covers the law's truth (:func:`_truth`: the white factor the law applies
while moving; the GM's σ and τ where the law has one, "none" where it has none: covered when the wander is reported
as a bound, i.e. not found; a bias term outside the group-wide GM/RW family is reported, not counted), with the
coverage per law and group and its exact 95 % interval (:func:`recovery_table`).
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

from imunoise.inuse import estimate_in_motion, summary_lines
from imunoise.inuse.estimate import GROUPS
from imunoise.io.atomic import atomic_write_text


def _truth(sc, moving: np.ndarray) -> dict:
    """Per group, what the drive's law injects while moving, in the estimator's terms, or why it is not in them.

    white: the factor f with f² the mean white-variance scale over the moving samples (the estimator's moving
    flag) and the group's axes (a speed-ramped law gives a spread, reported beside it); wander: the moving
    Gauss–Markov's σ, τ where all axes of the group share them, 0 where the law adds no bias term; a law whose
    bias terms the group-wide GM/RW family cannot express (per-axis multipliers of the static driving noise, a
    step at departures, axes that differ) is marked "not in the family" and not counted."""
    ls = sc.extra["law_schedule"]
    out = {}
    for g, idx in GROUPS.items():
        sl = slice(idx[0], idx[-1] + 1)  # a group's axes are contiguous; a view keeps the mean's summation order
        w = np.asarray(ls.white_var_scale)[moving][:, sl]
        sig, tau = np.asarray(ls.gm_sigma)[sl], np.asarray(ls.gm_tau_s)[sl]
        bvs = np.asarray(ls.bias_var_scale)[moving][:, sl]
        other = bool(np.any(np.abs(bvs - 1.0) > 1e-12) or np.any(np.asarray(ls.step_var)[sl] > 0)
                     or np.any(np.asarray(ls.warmup_rw_q)[sl] > 0))
        same = bool(np.all(sig == sig[0]) and np.all(tau == tau[0]))
        wander = None if other or not same else (float(sig[0]), float(tau[0]) if sig[0] > 0 else None)
        out[g] = {"white": float(np.sqrt(w.mean())), "white_range": [float(np.sqrt(w.min())), float(np.sqrt(w.max()))],
                  "wander": wander}
    return out


def _coverage(part, truth: dict) -> dict:
    """Per group: the estimate and whether each identifiable interval covers the truth (:func:`_truth`)."""
    out = {}
    for g, axis in (("gyro", "gyro_x"), ("accel", "accel_x")):
        ax = part.axes[axis]
        t = truth[g]
        row = {"truth": t, "white": ax.white_factor.to_dict(), "bias": ax.bias.to_dict(),
               "bound": part.bounds[axis].to_dict() if axis in part.bounds else None}
        if ax.white_factor.value is not None:
            row["white_covers"] = ax.white_factor.covers(t["white"])
        else:  # not identified: reported as the likelihood's upper bound, which holds the truth or not
            up = part.evidence.get("white_upper", {}).get(g)
            row["white_upper"] = up
            row["white_covers"] = bool(up is None or t["white"] <= up)
            row["white_as_bound"] = True
        if t["wander"] is None:
            row["wander_in_family"] = False
        else:
            s, tau = t["wander"]
            row["wander_in_family"] = True
            if s == 0:
                row["wander_covers"] = ax.bias.model == "none"
            elif ax.bias.model == "gm":
                ci = ax.bias.ci95
                row["wander_covers"] = bool(ci["sigma"][0] <= s <= ci["sigma"][1]
                                            and ci["tau_s"][0] <= tau <= ci["tau_s"][1])
            elif ax.bias.model == "rw":  # τ not identified: the driving density against the GM's
                ci = ax.bias.ci95["k"]
                row["wander_covers"] = bool(ci[0] <= math.sqrt(2.0 * s * s / tau) <= ci[1])
                row["wander_as_rw"] = True
            else:
                row["wander_covers"] = False
        out[g] = row
    return out


def _sim_one(job: tuple) -> dict:
    """One simulated drive's estimate (a process of the pool)."""
    from imunoise.experiments.common import simulate_scenario
    from imunoise.experiments.oracle_const import true_static_models
    from imunoise.inuse.likelihood import drive_moving

    law, seed, duration, stops = job
    sc = simulate_scenario(seed, duration_s=duration, motion_noise=law, n_outages=0, n_stops=stops)
    t0 = time.process_time()
    est = estimate_in_motion([sc], true_static_models(sc), freq=sc.rate, names=[sc.name])
    row = {"law": law, "seed": seed, "cpu_s": time.process_time() - t0, "runs": est.runs,
           "hours_moving": est.part.evidence["hours_moving"], "lr_wander": est.lr_wander,
           "lr_white_one": est.part.evidence.get("lr_white_one", {}),
           "dispersion": est.part.evidence.get("dispersion", {}),
           **_coverage(est.part, _truth(sc, drive_moving(sc)))}
    row["summary"] = summary_lines(est.part)
    return row


def run_sim(args) -> list:
    from concurrent.futures import ProcessPoolExecutor

    jobs = [(law, seed, args.duration, args.stops) for law in args.laws for seed in range(args.seeds[0], args.seeds[1])]
    rows = []
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        for k, row in enumerate(pool.map(_sim_one, jobs), 1):
            rows.append(row)
            print(f"[{k}/{len(jobs)}] {row['law']} {row['seed']}: {row['cpu_s']:.1f} s CPU, {row['runs']} runs",
                  *row["summary"][::3], sep="\n  ", flush=True)
            _write(args, rows)  # a stopped run keeps what it finished
    for line in recovery_table(rows):
        print(line)
    return rows


def _ci_prop(k: int, n: int) -> str:
    from scipy.stats import binomtest

    if n == 0:
        return "–"
    ci = binomtest(k, n).proportion_ci(0.95, method="exact")
    return f"{k}/{n} = {100 * k / n:.0f} % [{100 * ci.low:.0f}, {100 * ci.high:.0f}]"


def recovery_table(rows: list) -> list[str]:
    """Markdown: per law and group, the coverage of the white factor and of the wander (exact 95 % intervals)."""
    out = ["| law | group | truth: white factor (range) | white covers | of them as a bound | wander truth | "
           "wander covers | of them as a walk | CPU s per drive (median) |", "|" + "---|" * 9]
    for law in dict.fromkeys(r["law"] for r in rows):
        rs = [r for r in rows if r["law"] == law]
        cpu = float(np.median([r["cpu_s"] for r in rs]))
        for g in ("gyro", "accel"):
            t = rs[0][g]["truth"]
            wc = sum(bool(r[g]["white_covers"]) for r in rs)
            wb = sum(bool(r[g].get("white_as_bound")) for r in rs)
            fam = [r for r in rs if r[g]["wander_in_family"]]
            if not fam:
                wt, wcov, wrw = "not in the family", "not counted", "–"
            else:
                s, tau = t["wander"]
                wt = "none" if s == 0 else f"GM σ {s:.3g}, τ {tau:g} s"
                wcov = _ci_prop(sum(bool(r[g]["wander_covers"]) for r in fam), len(fam))
                wrw = str(sum(bool(r[g].get("wander_as_rw")) for r in fam))
            lo, hi = t["white_range"]
            out.append(f"| {law} | {g} | {t['white']:.3g} ({lo:.3g}–{hi:.3g}) | {_ci_prop(wc, len(rs))} | {wb} | "
                       f"{wt} | {wcov} | {wrw} | {cpu:.0f} |")
    return out


def _write(args, rows: list) -> None:
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out, json.dumps({"argv": sys.argv, "seed_role": getattr(args, "seed_role", None),
                                            "rows": rows}, indent=1, default=float))


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
    s.add_argument("--workers", type=int, default=1, help="processes (one drive each)")
    s.add_argument("--seed-role", choices=("development", "report"), default="development")
    s.add_argument("--out", required=True)
    r = sub.add_parser("real")
    r.add_argument("--static-model", required=True, help="model.json of calibrate on the drive's stops")
    r.add_argument("--out", required=True)
    args = p.parse_args(argv)
    rows = run_sim(args) if args.what == "sim" else run_real(args)
    _write(args, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
