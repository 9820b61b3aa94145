"""Carry-over of the in-use noise to the next drive of a vehicle, law by law, and the acceptance table
(docs/evidence/in_use_carry_over.md).

    python scripts/in_use_carry_over.py --laws none gyro_moving_gm accel_moving_gm drive0708 \
        gyro_departure_step warmup scripts/in_use_laws/white_x3.json scripts/in_use_laws/slow_wander.json \
        --seeds 20 --seed0 7100000 --out out/in_use/carry

Per law one ``imunoise experiment online --sim --vehicle-drives 2`` run (vehicles of two drives: ``in_use`` learns
on the first, every method is scored on the second; rows plain, static_var, gmwm, in_use, oracle_law;
meter-level GNSS, dense 60 s windows every 20 s, deterministic model timing), skipped when its
``results.json`` exists. Then, as the acceptance reads:

* no harm: ``in_use``/``gmwm`` upper bound ≤ 1.01 on ``none`` and every law without in-motion terms;
* useful: ``in_use``/``gmwm`` upper bound < 1 on every law where ``oracle_law``/``gmwm`` has its upper bound < 0.95;
  pooled over those laws, the share of ``oracle_law``'s log-gain over ``gmwm`` that ``in_use`` keeps, with a
  95 % percentile CI from a bootstrap over the vehicles (law, seed) (:func:`imunoise.experiments.stats.gain_share`);
* consistent: NEES of position + velocity inside its 95 % band, pooled over every law's vehicles, with its CI
  (:func:`imunoise.experiments.nees.nees_summary`).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

REGIME = "noise:1.5,3,1"
METHODS = "plain,static_var,gmwm,in_use,oracle_law"
NO_IN_MOTION = {"none", "warmup"}  # shipped laws without a motion-dependent term (warm-up follows the clock)


def _law_name(law: str) -> str:
    return Path(law).stem if law.endswith(".json") else law


def run_law(law: str, args, out: Path) -> Path:
    d = out / _law_name(law)
    if (d / "results.json").exists():
        print(f"{_law_name(law)}: results exist, not rerun ({d})", flush=True)
        return d
    cmd = [sys.executable, "-m", "imunoise", "experiment", "online", "--sim", "--vehicle-drives", "2",
           "--seeds", str(args.seeds), "--seed0", str(args.seed0), "--duration", str(args.duration),
           "--stops", str(args.stops), "--outages", "dense:60:20", "--gnss-regime", REGIME, "--noise-seeds", "1",
           "--methods", METHODS, "--pairs", "in_use/gmwm,oracle_law/gmwm,in_use/static_var,gmwm/static_var",
           "--motion-noise", law, "--latency", "0.5", "--workers", str(args.workers), "--out", str(d)]
    print(f"{_law_name(law)}: running {' '.join(cmd[2:])}", flush=True)
    t0 = time.time()
    subprocess.run(cmd, check=True)
    print(f"{_law_name(law)}: done in {(time.time() - t0) / 60:.1f} min wall", flush=True)
    return d


def _pair(res: dict, m: str, b: str) -> dict:
    return next(p for p in res["paired"] if p["method"] == m and p["baseline"] == b and p["metric"] == "drift"
                and p["gnss"] == REGIME)


def summarize(dirs: dict[str, Path]) -> dict:
    from imunoise.experiments.nees import nees_summary
    from imunoise.experiments.stats import drive_log_ratios, gain_share

    rows, groups, refs, units, nees_all = [], [], [], [], {}
    for law, d in dirs.items():
        res = json.loads((d / "results.json").read_text())
        iu, orc, gs = _pair(res, "in_use", "gmwm"), _pair(res, "oracle_law", "gmwm"), _pair(res, "in_use", "static_var")
        useful_law = orc["ci"][1] is not None and orc["ci"][1] < 0.95
        row = {"law": law, "vehicles": iu["n_clusters"], "in_use/gmwm": [iu["ratio"], *iu["ci"]],
               "oracle_law/gmwm": [orc["ratio"], *orc["ci"]], "in_use/static_var": [gs["ratio"], *gs["ci"]],
               "no_harm_law": law in NO_IN_MOTION, "oracle_useful": useful_law}
        if law in NO_IN_MOTION:
            row["no_harm_met"] = iu["ci"][1] <= 1.01
        if useful_law:
            row["useful_met"] = iu["ci"][1] < 1.0
            drift = res["per_window"][REGIME]["drift"]
            for k, (a, b, o) in enumerate(zip(drift["in_use"], drift["gmwm"], drift["oracle_law"], strict=True)):
                groups.append(drive_log_ratios(a, b))
                refs.append(drive_log_ratios(o, b))
                units.append(f"{law}/{k}")
        nees = res["nees"][REGIME]
        row["nees"] = {m: [nees[m]["share_inside"], *nees[m]["ci95"]] for m in nees}
        for m, s in nees.items():
            nees_all.setdefault(m, []).extend(s.get("per_drive", []))
        rows.append(row)
    share = gain_share(groups, refs, units=units, seed=0) if groups else None
    pooled_nees = {m: nees_summary(v) for m, v in nees_all.items()}
    for v in pooled_nees.values():
        v.pop("per_drive", None)
    return {"regime": REGIME, "laws": rows, "share_of_oracle_gain": share, "nees_pooled": pooled_nees}


def _pct(n: dict, m: str) -> str:
    return "–" if m not in n or n[m][0] is None else f"{100 * n[m][0]:.1f} % [{100 * n[m][1]:.1f}, {100 * n[m][2]:.1f}]"


def markdown(s: dict) -> str:
    def r(x):
        return "–" if x is None or x[0] is None else f"{x[0]:.3f} [{x[1]:.3f}, {x[2]:.3f}]"

    out = ["| law | vehicles | in_use / gmwm | oracle_law / gmwm | in_use / static_var | NEES in band: gmwm | "
           "in_use | oracle_law |", "|---|---|---|---|---|---|---|---|"]
    for row in s["laws"]:
        n = row["nees"]
        out.append(f"| {row['law']} | {row['vehicles']} | {r(row['in_use/gmwm'])} | {r(row['oracle_law/gmwm'])} | "
                   f"{r(row['in_use/static_var'])} | {_pct(n, 'gmwm')} | {_pct(n, 'in_use')} | "
                   f"{_pct(n, 'oracle_law')} |")
    sh = s["share_of_oracle_gain"]
    if sh and sh["share"] is not None:
        out.append(f"\nShare of oracle_law's log-gain over gmwm kept by in_use, pooled over the laws where "
                   f"oracle_law / gmwm < 0.95 (upper bound): {100 * sh['share']:.1f} % "
                   f"[{100 * sh['ci'][0]:.1f}, {100 * sh['ci'][1]:.1f}] ({sh['n_clusters']} vehicles)")
    else:
        out.append("\nNo law has oracle_law / gmwm with an upper bound < 0.95: no gain share to pool.")
    for m, v in s["nees_pooled"].items():
        if v["share_inside"] is not None:
            out.append(f"- NEES pooled, {m}: {100 * v['share_inside']:.1f} % [{100 * v['ci95'][0]:.1f}, "
                       f"{100 * v['ci95'][1]:.1f}] of {v['epochs']} epochs, {v['drives']} drives")
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--laws", nargs="+", required=True, help="law names or law files (.json)")
    p.add_argument("--seeds", type=int, default=20, help="vehicles per law")
    p.add_argument("--seed0", type=int, required=True)
    p.add_argument("--duration", type=float, default=600.0, help="drive length [s]")
    p.add_argument("--stops", type=int, default=4)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--out", required=True)
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    dirs = {_law_name(law): run_law(law, args, out) for law in args.laws}
    s = summarize(dirs)
    (out / "carry_over.json").write_text(json.dumps(s, indent=1))
    (out / "carry_over.md").write_text(markdown(s))
    print(markdown(s))
    print(f"wrote {out / 'carry_over.json'}, {out / 'carry_over.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
