"""Where the in-use gap is: the constant-model ceilings against ``in_use`` and ``oracle_law``, law by law
(docs/evidence/in_use_ceiling.md).

    nice -n 10 python scripts/in_use_ceiling.py --laws gyro_departure_step --seeds 10 --seed0 7400030 \
        --out out/in_use/ceiling

Per law ``imunoise experiment online --sim --vehicle-drives 2`` runs in the carry-over protocol of
``scripts/in_use_carry_over.py`` (vehicles of two 600 s drives with 4 stops, ``in_use`` learns on the first, every
row is scored on the second; meter-level GNSS ``noise:1.5,3,1``, dense 60 s windows every 20 s, latency 0.5 s), rows
gmwm, in_use, oracle_const, oracle_const_gmwm, oracle_law (:mod:`imunoise.experiments.oracle_const`), in batches
of ``--batch`` vehicles (``out/LAW/sSEED``; a batch whose ``results.json`` exists is not rerun, so a stopped run
keeps what it finished). ``--laws`` and ``--seed0`` pair up: law i gets the vehicles seed0_i … seed0_i + seeds − 1
(one seed0: the same for every law). Then, per law and pooled over the laws, the share of ``oracle_law``'s log-gain
over ``gmwm`` that each row keeps (:func:`imunoise.experiments.stats.gain_share`, 95 % percentile CI from a bootstrap
over the vehicles (law, seed), as the carry-over acceptance computes it).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REGIME = "noise:1.5,3,1"
ROWS = ("in_use", "oracle_const", "oracle_const_gmwm", "oracle_law")
METHODS = "gmwm," + ",".join(ROWS)
PAIRS = "in_use/gmwm,oracle_const/gmwm,oracle_const_gmwm/gmwm,oracle_law/gmwm,in_use/oracle_const_gmwm," \
        "oracle_const_gmwm/oracle_const,oracle_const/oracle_law"


def run_law(law: str, seed0: int, args, out: Path) -> list[Path]:
    """The law's vehicles in batches of ``--batch`` (one experiment run each, ``out/LAW/sSEED``), so that a run
    stopped midway keeps the batches it finished; a batch whose ``results.json`` exists is not rerun."""
    done = []
    for b0 in range(seed0, seed0 + args.seeds, args.batch):
        d = out / law / f"s{b0}"
        n = min(args.batch, seed0 + args.seeds - b0)
        if not (d / "results.json").exists():
            cmd = [sys.executable, "-m", "imunoise", "experiment", "online", "--sim", "--vehicle-drives", "2",
                   "--seeds", str(n), "--seed0", str(b0), "--duration", str(args.duration), "--stops",
                   str(args.stops), "--outages", "dense:60:20", "--gnss-regime", REGIME, "--noise-seeds", "1",
                   "--methods", METHODS, "--pairs", PAIRS, "--motion-noise", law, "--latency", "0.5",
                   "--workers", str(args.workers), "--out", str(d)]
            print(f"{law}: running {' '.join(cmd[2:])}", flush=True)
            t0 = time.time()
            subprocess.run(cmd, check=True)
            print(f"{law}: seeds {b0}-{b0 + n - 1} done in {(time.time() - t0) / 60:.1f} min wall", flush=True)
        done.append(d)
    return done


def _finished(out: Path, law: str) -> list[Path]:
    return sorted(p.parent for p in (out / law).glob("s*/results.json"))


def summarize(dirs: dict[str, list[Path]]) -> dict:
    """Per law (its batches pooled: the vehicles are the clusters) the paired drift ratios of :data:`PAIRS` and the
    shares of ``oracle_law``'s log-gain over ``gmwm``; the shares pooled over the laws."""
    from imunoise.experiments.stats import drive_log_ratios, gain_share, paired_entry

    laws, pooled = [], {m: ([], [], []) for m in ROWS[:-1]}
    for law, ds in dirs.items():
        drift: dict[str, list] = {}
        seeds: list[int] = []
        for d in ds:
            res = json.loads((d / "results.json").read_text())
            seeds += res["seeds"]
            for m, v in res["per_window"][REGIME]["drift"].items():
                drift.setdefault(m, []).extend(v)
        if not seeds:
            continue
        units = [f"{law}/{s}" for s in seeds]
        ratios = {}
        for p in PAIRS.split(","):
            e = paired_entry(*p.split("/"), "drift", drift, seed=0)
            ratios[p] = [e["ratio"], *e["ci"]]
        row = {"law": law, "vehicles": len(seeds), "seeds": [min(seeds), max(seeds)], "ratios": ratios, "share": {},
               "mean_drift_m": {m: float(np.nanmean([x for v in drift[m] for x in np.ravel(np.array(v, dtype=float))]))
                                for m in ("gmwm", *ROWS)}}
        refs = [drive_log_ratios(o, b) for o, b in zip(drift["oracle_law"], drift["gmwm"], strict=True)]
        for m in ROWS[:-1]:
            g = [drive_log_ratios(a, b) for a, b in zip(drift[m], drift["gmwm"], strict=True)]
            row["share"][m] = gain_share(g, refs, units=units, seed=0)
            pooled[m][0].extend(g)
            pooled[m][1].extend(refs)
            pooled[m][2].extend(units)
        laws.append(row)
    share = {m: gain_share(g, r, units=u, seed=0) for m, (g, r, u) in pooled.items() if g}
    return {"regime": REGIME, "laws": laws, "pooled_share": share}


def run_family(law: str, seed0: int, args, out: Path) -> None:
    """``--family``: the model-family gap alone, in-process and cheap (no learning, no online engine): per vehicle
    (the scored drive only) the batch filter with the truth's static model and no in-motion part (``static_truth``:
    the in_use family at white factor 1 and no wander), ``oracle_const`` and ``oracle_law``, all on the same static
    part, written to ``out/family/LAW/SEED.json`` as each vehicle finishes."""
    from imunoise.experiments import dense
    from imunoise.experiments.common import simulate_scenario
    from imunoise.experiments.gnss_regimes import parse_gnss
    from imunoise.experiments.oracle_const import run_windows_const, true_static_models
    from imunoise.experiments.oracle_law import run_windows_law
    from imunoise.online import OnlineConfig

    base = OnlineConfig(latency=0.5)
    rg = parse_gnss(REGIME)
    for seed in range(seed0, seed0 + args.seeds):
        f = out / "family" / law / f"{seed}.json"
        if f.exists():
            continue
        t0 = time.process_time()
        sc = simulate_scenario(seed, n_outages=0, duration_s=args.duration, n_stops=args.stops, streams=[],
                               motion_noise=law)
        windows = dense.dense_windows(sc, dense.parse_outages("dense:60:20")[1])
        gnss = rg.apply(sc.gnss, 1_000_003 * seed + 1)  # as the experiment's first noise seed
        rows = {"static_truth": run_windows_law(sc, gnss, windows, base=base, models=true_static_models(sc, base)),
                "oracle_const": run_windows_const(sc, gnss, windows, base=base),
                "oracle_law": run_windows_law(sc, gnss, windows, base=base)}
        if args.gmwm_static:  # in_use's static part: the gmwm row's fits on the vehicle's earlier drive
            pairs = _in_use_static(seed, law, args, base)
            rows["gmwm_static"] = run_windows_law(sc, gnss, windows, base=base, models=pairs)
            rows["oracle_const_gmwm"] = run_windows_const(sc, gnss, windows, base=base, models=pairs)
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text(json.dumps({"seed": seed, "law": law, "windows": windows, "oracle_const": rows["oracle_const"][
            "oracle_const"], "drift": {m: [w["drift"] for w in r["windows"]] for m, r in rows.items()},
            "cpu_s": time.process_time() - t0}))
        means = {m: np.nanmean(np.array([w["drift"] for w in r["windows"]], dtype=float)) for m, r in rows.items()}
        print(f"{law} {seed}: " + ", ".join(f"{m} {v:.1f} m" for m, v in means.items())
              + f" ({time.process_time() - t0:.0f} s CPU)", flush=True)


def _in_use_static(seed: int, law: str, args, base) -> list:
    """``in_use``'s static filter models for vehicle ``seed`` (:func:`imunoise.experiments.in_use_method.learn_in_use`
    without its in-motion estimate): the ``gmwm`` row's fits on the earlier drive, in the run's GNSS regime."""
    from imunoise.experiments.carry_over import earlier_scenarios, learning_drives
    from imunoise.experiments.common import filter_models
    from imunoise.experiments.dense_warm import gmwm_on_drives
    from imunoise.experiments.gnss_regimes import parse_gnss

    kw = {"duration_s": args.duration, "n_stops": args.stops, "streams": [], "motion_noise": law}
    d = learning_drives(seed, 2, earlier_scenarios(seed, 1, **kw), parse_gnss(REGIME), 1)
    return filter_models(list(gmwm_on_drives(d, base).fits), d[0][0].rate, base.with_(ekf=d[0][0].ekf_config()))


def summarize_family(out: Path, laws) -> dict:
    """Per law and pooled, against each baseline B (``static_truth``; ``gmwm_static`` where run): the ratios of the
    rows over B and over ``oracle_law``, and the share of ``oracle_law``'s log-gain over B that each row keeps
    (vehicles the clusters)."""
    from imunoise.experiments.stats import drive_log_ratios, gain_share, paired_entry

    rows, pooled = [], {}
    for law in laws:
        vs = [json.loads(p.read_text()) for p in sorted((out / "family" / law).glob("*.json"))]
        if not vs:
            continue
        names = [m for m in vs[0]["drift"] if all(m in v["drift"] for v in vs)]
        drift = {m: [v["drift"][m] for v in vs] for m in names}
        units = [f"{law}/{v['seed']}" for v in vs]
        row = {"law": law, "vehicles": len(vs), "seeds": [vs[0]["seed"], vs[-1]["seed"]], "ratios": {},
               "share": {}, "mean_drift_m": {m: float(np.nanmean(np.array(drift[m], dtype=float))) for m in names},
               "cpu_s": float(np.mean([v["cpu_s"] for v in vs]))}
        for b in (x for x in ("static_truth", "gmwm_static") if x in names):
            ref = [drive_log_ratios(o, y) for o, y in zip(drift["oracle_law"], drift[b], strict=True)]
            for m in (x for x in names if x not in (b, "oracle_law")):
                e = paired_entry(m, b, "drift", drift, seed=0)
                row["ratios"][f"{m}/{b}"] = [e["ratio"], *e["ci"]]
                g = [drive_log_ratios(x, y) for x, y in zip(drift[m], drift[b], strict=True)]
                row["share"][f"{m}/{b}"] = gain_share(g, ref, units=units, seed=0)
                acc = pooled.setdefault(f"{m}/{b}", ([], [], []))
                acc[0].extend(g)
                acc[1].extend(ref)
                acc[2].extend(units)
            e = paired_entry("oracle_law", b, "drift", drift, seed=0)
            row["ratios"][f"oracle_law/{b}"] = [e["ratio"], *e["ci"]]
        for m in (x for x in names if x != "oracle_law"):
            e = paired_entry(m, "oracle_law", "drift", drift, seed=0)
            row["ratios"][f"{m}/oracle_law"] = [e["ratio"], *e["ci"]]
        rows.append(row)
    share = {k: dict(gain_share(g, r, units=u, seed=0), vehicles=len(set(u))) for k, (g, r, u) in pooled.items()}
    return {"regime": REGIME, "laws": rows, "pooled_share": share}


def markdown_family(s: dict) -> str:
    """Two tables: on the truth's static part (the model-family gap) and on ``in_use``'s (``--gmwm-static``)."""
    def ratio(row, k):
        return _r(row["ratios"].get(k))

    def pooled(k):
        v = s["pooled_share"].get(k)
        return f"{_s(v)} ({v['vehicles']} vehicles)" if v else "–"

    out = ["| law | vehicles | mean drift static_truth / oracle_const / oracle_law [m] | oracle_law / static_truth | "
           "oracle_const / oracle_law | share kept by oracle_const |", "|---|---|---|---|---|---|"]
    for row in s["laws"]:
        md = row["mean_drift_m"]
        out.append(f"| {row['law']} | {row['vehicles']} | {md['static_truth']:.1f} / {md['oracle_const']:.1f} / "
                   f"{md['oracle_law']:.1f} | {ratio(row, 'oracle_law/static_truth')} | "
                   f"{ratio(row, 'oracle_const/oracle_law')} | {_s(row['share'].get('oracle_const/static_truth'))} |")
    out.append(f"| pooled | | | | | {pooled('oracle_const/static_truth')} |")
    if not any("gmwm_static" in r["mean_drift_m"] for r in s["laws"]):
        return "\n".join(out) + "\n"
    out += ["", "| law | mean drift gmwm_static / oracle_const_gmwm [m] | gmwm_static / static_truth | oracle_law / "
            "gmwm_static | oracle_const_gmwm / oracle_law | share kept by the truth's static part | share kept by "
            "oracle_const_gmwm |", "|---|---|---|---|---|---|---|"]
    for row in (r for r in s["laws"] if "gmwm_static" in r["mean_drift_m"]):
        md = row["mean_drift_m"]
        out.append(f"| {row['law']} | {md['gmwm_static']:.1f} / {md['oracle_const_gmwm']:.1f} | "
                   f"{ratio(row, 'gmwm_static/static_truth')} | {ratio(row, 'oracle_law/gmwm_static')} | "
                   f"{ratio(row, 'oracle_const_gmwm/oracle_law')} | {_s(row['share'].get('static_truth/gmwm_static'))}"
                   f" | {_s(row['share'].get('oracle_const_gmwm/gmwm_static'))} |")
    out.append(f"| pooled | | | | | {pooled('static_truth/gmwm_static')} | {pooled('oracle_const_gmwm/gmwm_static')} |")
    return "\n".join(out) + "\n"


def _r(x) -> str:
    return "–" if x is None or x[0] is None else f"{x[0]:.3f} [{x[1]:.3f}, {x[2]:.3f}]"


def _s(sh) -> str:
    if not sh or sh["share"] is None:
        return "–"
    return f"{100 * sh['share']:.1f} % [{100 * sh['ci'][0]:.1f}, {100 * sh['ci'][1]:.1f}]"


def markdown(s: dict) -> str:
    pairs = PAIRS.split(",")
    out = ["| law | vehicles | " + " | ".join(p.replace("/", " / ") for p in pairs) + " |",
           "|---|---|" + "---|" * len(pairs)]
    for row in s["laws"]:
        out.append(f"| {row['law']} | {row['vehicles']} | " + " | ".join(_r(row["ratios"][p]) for p in pairs) + " |")
    out += ["", "Share of oracle_law's log-gain over gmwm kept (95 % CI, bootstrap over vehicles):", "",
            "| law | vehicles | " + " | ".join(ROWS[:-1]) + " |", "|---|---|" + "---|" * (len(ROWS) - 1)]
    for row in s["laws"]:
        out.append(f"| {row['law']} | {row['vehicles']} | " + " | ".join(_s(row["share"][m]) for m in ROWS[:-1])
                   + " |")
    n = sum(r["vehicles"] for r in s["laws"])
    out.append(f"| pooled | {n} | " + " | ".join(_s(s["pooled_share"].get(m)) for m in ROWS[:-1]) + " |")
    out += ["", "Mean end-of-window drift [m]:", "", "| law | gmwm | " + " | ".join(ROWS) + " |",
            "|---|---|" + "---|" * len(ROWS)]
    for row in s["laws"]:
        out.append(f"| {row['law']} | " + " | ".join(f"{row['mean_drift_m'][m]:.1f}" for m in ("gmwm", *ROWS)) + " |")
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--laws", nargs="+", required=True, help="shipped law names")
    p.add_argument("--seed0", type=int, nargs="+", required=True, help="first vehicle seed, one per law or one")
    p.add_argument("--seeds", type=int, default=10, help="vehicles per law")
    p.add_argument("--duration", type=float, default=600.0, help="drive length [s]")
    p.add_argument("--stops", type=int, default=4)
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--batch", type=int, default=2, help="vehicles per experiment run (a stopped run keeps its batches)")
    p.add_argument("--family", action="store_true", help="the model-family gap alone: rows static_truth, "
                   "oracle_const, oracle_law on the scored drive, in-process (run_family)")
    p.add_argument("--gmwm-static", action="store_true", help="with --family: also in_use's static part (the "
                   "gmwm row's fits on the earlier drive) alone (gmwm_static) and under the constant part "
                   "(oracle_const_gmwm)")
    p.add_argument("--summary-only", action="store_true", help="summarize the laws whose results.json exist")
    p.add_argument("--out", required=True)
    args = p.parse_args(argv)
    if len(args.seed0) not in (1, len(args.laws)):
        p.error(f"--seed0: give one seed or one per law ({len(args.laws)}), got {len(args.seed0)}")
    seeds0 = args.seed0 * len(args.laws) if len(args.seed0) == 1 else args.seed0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.family:
        if not args.summary_only:
            for law, s0 in zip(args.laws, seeds0, strict=True):
                run_family(law, s0, args, out)
        fs = summarize_family(out, args.laws)
        (out / "family.json").write_text(json.dumps(fs, indent=1))
        (out / "family.md").write_text(markdown_family(fs))
        print(markdown_family(fs))
        return 0
    if not args.summary_only:
        for law, s0 in zip(args.laws, seeds0, strict=True):
            run_law(law, s0, args, out)
    dirs = {law: _finished(out, law) for law in args.laws}
    s = summarize(dirs)
    (out / "ceiling.json").write_text(json.dumps(s, indent=1))
    (out / "ceiling.md").write_text(markdown(s))
    print(markdown(s))
    print(f"wrote {out / 'ceiling.json'}, {out / 'ceiling.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
