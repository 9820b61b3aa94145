"""`imunoise experiment denial|online`: the paper's two experiments (SPEC §11) with a report."""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

from imunoise.errors import ImunoiseError

EXAMPLES = """examples:
  imunoise experiment online --data data/drive_0708 --out out/exp_online
  imunoise experiment online --sim --seeds 20 --out out/mc_online          # Monte Carlo, both cores
  imunoise experiment denial --sim --seeds 20 --out out/mc_denial
  imunoise experiment denial --data ../shared/data/rtklibexplorer_drive0708 --out out/denial_real

Writes DIR/report.html (one self-contained page), DIR/report.md, DIR/results.json (SPEC §11 keys:
methods → horizontal_rms_m, vertical_rms_m, ecef_rms_m, outage_end_horizontal_m, mean_outage_end_horizontal_m;
timing; seeds and per_seed for Monte Carlo), CSV tables (headline.csv, outages.csv, differences.csv or
sections.csv) and PNG figures. Lengths in m, times in s."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "experiment",
        help="the paper's experiments: GNSS denial (Table 1) and online GNSS-available (Tables 5-6)",
        description="Run the GNSS-denial or the online experiment on a dataset folder or the simulator.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("which", choices=("denial", "online"), help="which experiment")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--sim", action="store_true", help="Monte Carlo on simulated drives (SPEC §10)")
    src.add_argument("--data", help="dataset folder with dataset.json and a reference (default: data/drive_0708)")
    p.add_argument("--seeds", type=int, default=20, help="simulator: number of seeds (default 20)")
    p.add_argument("--seed0", type=int, default=0, help="simulator: first seed (default 0)")
    p.add_argument("--duration", type=float, default=600.0, help="simulator: drive length [s] (default 600)")
    p.add_argument("--stops", type=int, default=4, help="simulator: traffic-light stops (default 4)")
    p.add_argument("--outages", type=int, default=4, help="simulator: 60 s outages per drive (default 4)")
    p.add_argument("--imu", default=None,
                   help="simulator: IMU error models: preset (paper, mems, tactical), structure, or model JSON "
                   "(imunoise.sim.resolve_imu_models; default: paper = gyros of paper Table 4 and mems "
                   "accelerometers, 3*AR1+WN+RW per axis)")
    p.add_argument("--static-hours", type=float, default=2.0, help="denial --sim: static recording [h] (default 2)")
    p.add_argument("--methods", help="comma-separated subset of the methods")
    p.add_argument("--start", type=float, help="real data: navigation start [s, data time base]")
    p.add_argument("--workers", type=int, default=2, help="parallel processes (default 2)")
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(func=run)


def _progress(total: int, desc: str):
    from tqdm import tqdm

    bar = tqdm(total=total, desc=desc, unit="job", disable=not sys.stderr.isatty())

    def step(_name=None) -> None:
        bar.update(1)

    return bar, step


def run(args: argparse.Namespace) -> int:
    from imunoise.experiments import denial, online_exp
    from imunoise.experiments.common import repo_data_dir
    from imunoise.experiments.report import headline_rows, write_denial_real, write_online_real, write_sim
    from imunoise.report import fmt

    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    mod = denial if args.which == "denial" else online_exp
    default = mod.METHODS if (args.which == "denial" or not args.sim) else online_exp.MC_METHODS
    methods = tuple(m.strip() for m in args.methods.split(",")) if args.methods else default
    bad = [m for m in methods if m not in mod.METHODS]
    if bad:
        raise ImunoiseError(f"unknown method(s) {bad}; choose from {', '.join(mod.METHODS)}")
    if args.sim:
        if args.seeds < 1:
            raise ImunoiseError(f"--seeds must be ≥ 1, got {args.seeds}")
        seeds = list(range(args.seed0, args.seed0 + args.seeds))
        bar, step = _progress(len(seeds), f"{args.which} Monte Carlo")
        kw = {"duration_s": args.duration, "n_stops": args.stops, "n_outages": args.outages}
        if args.imu:
            kw["imu_models"] = args.imu
        if args.which == "denial":
            res = denial.run_sim(seeds, methods=methods, workers=args.workers,
                                 static_recording_s=3600.0 * args.static_hours, progress=step, **kw)
        else:
            res = online_exp.run_sim(seeds, methods=methods, workers=args.workers, progress=step, **kw)
        bar.close()
        html = write_sim(res, out, title=f"imunoise: {args.which} experiment, Monte Carlo ({len(seeds)} seeds)")
    else:
        data = args.data or str(repo_data_dir())
        n_runs = len(methods) * 6 if args.which == "online" else len(methods)
        bar, step = _progress(n_runs, f"{args.which} experiment")
        if args.which == "denial":
            res, sc = denial.run_real(data, methods=methods, start=args.start, progress=step)
            bar.close()
            html = write_denial_real(res, sc, out)
        else:
            res, sc = online_exp.run_real(data, methods=methods, workers=args.workers, start=args.start, progress=step)
            bar.close()
            html = write_online_real(res, sc, out)
    _print_headline(headline_rows(res), fmt)
    print(f"\nreport: {html.resolve()}  ({time.perf_counter() - t0:.1f} s)")
    return 0


def _print_headline(rows, fmt) -> None:
    heads = ["method", "horiz. RMS [m]", "vert. RMS [m]", "mean outage drift [m]", "Δ vs plain [%]"]
    table = [[r[0].split(" (")[0], fmt(r[1]), fmt(r[2]), fmt(r[4]), fmt(r[5])] for r in rows]
    w = [max(len(h), *(len(t[i]) for t in table)) for i, h in enumerate(heads)]
    print("  ".join(h.ljust(w[i]) for i, h in enumerate(heads)))
    for t in table:
        print("  ".join(c.ljust(w[i]) for i, c in enumerate(t)))
