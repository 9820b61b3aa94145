"""Cross-fit of the in-use noise on the halves of one real drive (docs/evidence/in_use_real_drive.md): the ``in_use``
model is estimated on one half of the drive and the other half's dense windows are navigated, both ways, under RTK
and meter-level GNSS; paired with ``gmwm``, ``static_var`` and ``gmwm_hindsight`` (the in_use model's own static
part), the NEES of position + velocity against the RTK reference in the scored half, and the estimated factors.

    PYTHONPATH=src python scripts/in_use_real_halves.py --out out/in_use_halves/dev --noise-seeds 2

Each direction is one ``imunoise experiment online --data DATA --outages dense:60:2 --learn-half first|second``
run (:func:`imunoise.experiments.dense.run_real`, :mod:`imunoise.experiments.drive_halves`); this script runs both
and writes DIR/results.json (both runs' results and the summary) and DIR/in_use_real_halves.md. The intervals
are those the dense-window evidence gives one drive: a fixed-b t over the windows (Bartlett long-run variance,
bandwidth = number of windows, AR(1)-calibrated critical value; :mod:`imunoise.experiments.fixed_b`), the GNSS
noise seeds averaged per window first.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

PAIRS = (("in_use", "gmwm"), ("in_use", "static_var"), ("gmwm", "static_var"), ("in_use", "gmwm_hindsight"),
         ("gmwm_hindsight", "static_var"), ("in_use", "plain"))
METHODS = ("plain", "static_var", "gmwm", "gmwm_hindsight", "in_use")


def _fmt_ratio(e: dict | None) -> str:
    if e is None or e.get("ratio") is None:
        return "–"
    lo, hi = e["ci"]
    s = f"{e['ratio']:.3f} [{lo:.3f}, {hi:.3f}]"
    return f"**{s}**" if e["significant"] else s


def _num(x: float | None) -> str:
    return "–" if x is None else f"{x:.1f}"


def _entry(res: dict, gnss: str, a: str, b: str, metric: str) -> dict | None:
    for e in res["paired"]:
        if (e["gnss"], e["method"], e["baseline"], e["metric"]) == (gnss, a, b, metric):
            return e
    return None


def _factor_lines(res: dict) -> list[str]:
    from imunoise.inuse import summary_lines
    from imunoise.noise.in_motion import InMotionPart

    out = []
    for key, m in res["in_use_models"].items():
        part = m["in_motion"]
        lr = part["evidence"].get("lr_wander", {})
        out.append(f"- `{key}` ({m['filter_runs']} filter runs, {m['cpu_s']:.1f} s CPU; LR of the wander: "
                   + ", ".join(f"{g} {v:.2f}" for g, v in lr.items()) + ")")
        out += [f"  - {line}" for line in summary_lines(InMotionPart.from_dict(part))]
    return out


def markdown(runs: dict[str, dict], meta: dict) -> str:
    """The tables of both directions: paired end-drift and window-RMS ratios, mean drifts, NEES, factors."""
    lines = [f"# In-use noise cross-fitted on the halves of {meta['data']} ({meta['seed_role']})", "",
             f"Command: `{meta['command']}` (commit {meta['commit']})", "",
             f"Windows {meta['outages']}; noise seeds {meta['noise_seeds']}; wall {meta['wall_s']:.0f} s, CPU "
             f"{meta['cpu_s']:.0f} s (this process and its workers). Ratio = geometric mean over the windows of "
             "method / baseline; 95 % interval: one drive, fixed-b t over the windows; **bold**: the interval "
             "excludes 1.", ""]
    for learn, res in runs.items():
        sp = res["halves"]["spans_s"]
        scored = "second" if learn == "first" else "first"
        lo, hi = sp[scored]
        lines += [f"## Learn on the {learn} half, score the {scored} half [{lo:.1f}, {hi:.1f}) s", "",
                  f"{res['n_windows']} windows ({res['n_independent']} share no data).", "",
                  "| GNSS | pair | end drift | window RMS |", "|---|---|---|---|"]
        for g in res["gnss"]:
            for a, b in PAIRS:
                if a in res["methods"] and b in res["methods"]:
                    lines.append(f"| {g} | {a} / {b} | {_fmt_ratio(_entry(res, g, a, b, 'drift'))} | "
                                 f"{_fmt_ratio(_entry(res, g, a, b, 'rms'))} |")
        lines += ["", "| GNSS | method | mean end drift [m] | mean window RMS [m] | NEES pos+vel inside 95 % band "
                  "[% of epochs] | mean NEES | epochs |", "|---|---|---|---|---|---|---|"]
        for g in res["gnss"]:
            for m in res["methods"]:
                s, n = res["summary"][g][m], res["nees"][g][m]
                share = "–" if n["share_inside"] is None else f"{100 * n['share_inside']:.1f}"
                mean = "–" if n["mean_nees"] is None else f"{n['mean_nees']:.3g}"
                d, r = s["mean_end_drift_m"], s["mean_window_rms_m"]
                lines.append(f"| {g} | {m} | {_num(d)} | {_num(r)} | {share} | "
                             f"{mean} | {n['epochs']} |")
        lines += ["", "Estimated in-motion factors (per axis; the three axes of a sensor group share them):", "",
                  *_factor_lines(res), ""]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", default=None, help="dataset folder (default: data/drive_0708)")
    p.add_argument("--outages", default="dense:60:2", help="dense:L:S[:LEAD] windows (default dense:60:2)")
    p.add_argument("--gnss-regime", action="append", default=None,
                   help="GNSS regime, repeatable (default: rtk and noise:1.5,3,1)")
    p.add_argument("--noise-seeds", type=int, default=2, help="GNSS noise seeds of the noise regimes (default 2)")
    p.add_argument("--noise-seed0", type=int, default=1, help="first GNSS noise seed (default 1)")
    p.add_argument("--methods", default=",".join(METHODS), help="rows (default " + ",".join(METHODS) + ")")
    p.add_argument("--latency", type=float, default=0.5,
                   help="fixed delay [s] from a stop's end to its model in gmwm's filter (a rerun repeats to the bit; "
                   "default 0.5)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--bootstrap", type=int, default=2000)
    p.add_argument("--seed-role", choices=("dev", "report"), default="dev")
    p.add_argument("--out", required=True, help="output folder")
    args = p.parse_args(argv)

    from imunoise.experiments import dense
    from imunoise.experiments.common import repo_data_dir
    from imunoise.experiments.gnss_regimes import parse_gnss
    from imunoise.online import OnlineConfig

    data = args.data or str(repo_data_dir())
    _, spec = dense.parse_outages(args.outages)
    regimes = [parse_gnss(g) for g in (args.gnss_regime or ["rtk", "noise:1.5,3,1"])]
    seeds = list(range(args.noise_seed0, args.noise_seed0 + args.noise_seeds))
    methods = tuple(m.strip() for m in args.methods.split(",") if m.strip())
    if args.seed_role == "report":  # refused before anything runs: a report label must be true
        from imunoise.experiments.report_tables import seed_role_problem

        why = seed_role_problem(sim=False, noise_seeds=seeds if any(r.random for r in regimes) else ())
        if why:
            raise SystemExit(f"--seed-role report: {why}")
    pairs = [(a, b) for a, b in PAIRS if a in methods and b in methods and b not in ("plain", "static_var")]
    import subprocess

    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                            cwd=Path(__file__).parent).stdout.strip()  # the code the numbers come from
    t0, c0 = time.perf_counter(), time.process_time()
    runs = {}
    for learn in ("first", "second"):
        print(f"[{time.perf_counter() - t0:7.1f} s] learning in_use on the {learn} half "
              f"({sum(len(seeds) if r.random else 1 for r in regimes)} GNSS realisations) ...", flush=True)
        done = [0]

        def step(name, learn=learn, done=done) -> None:
            done[0] += 1
            print(f"[{time.perf_counter() - t0:7.1f} s] learn {learn}: {name} done ({done[0]} runs)", flush=True)

        runs[learn] = dense.run_real(data, spec=spec, regimes=regimes, noise_seeds=seeds, methods=methods,
                                     pairs=pairs, workers=args.workers, base=OnlineConfig(latency=args.latency),
                                     n_boot=args.bootstrap, progress=step, learn_half=learn)
    import resource

    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    meta = {"command": " ".join(["python", *sys.argv]), "commit": commit, "data": data, "outages": spec.label,
            "noise_seeds": seeds, "seed_role": args.seed_role, "wall_s": time.perf_counter() - t0,
            "cpu_s": time.process_time() - c0 + ch.ru_utime + ch.ru_stime}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps({"meta": meta, "runs": runs}, indent=1, default=float))
    (out / "in_use_real_halves.md").write_text(markdown(runs, meta))
    print(f"wrote {out / 'in_use_real_halves.md'} and results.json ({meta['wall_s']:.0f} s wall, "
          f"{meta['cpu_s']:.0f} s CPU)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
