"""In-use noise carried to the next drive on the real noise of several IMU units (the ADIS16405 replay): per
recording (one unit), the dense-window evidence on simulated vehicles of K drives whose IMU errors are the unit's
own recording (``imunoise experiment online --sim --imu-noise FILE.npz --vehicle-drives K``; every drive of every
vehicle replays its own, disjoint stretch of the recording, :mod:`imunoise.sim.replay`), then pooled with the
units as the clusters:

* the paired end-drift ratios ``in_use/gmwm`` and ``in_use/static_var`` (and ``gmwm/static_var`` beside them),
  geometric means with the 95 % cluster-t interval over the units (df = units − 1; drives and windows nested
  inside, :func:`imunoise.experiments.stats.paired_entry` with ``units``), and the acceptance reading
  "in_use/gmwm upper bound ≤ 1.01";
* the share of unit-axes whose estimated in-use factor interval contains 1 (the white factor of every axis, and
  the K factor where the estimate gives one), each estimate (one vehicle's earlier drives, one GNSS realisation,
  one axis) one trial. A factor the data do not identify has no interval (only a bound): it is counted apart and
  enters a second share, labelled as counting it, never the first. A K factor of exactly 1 [1, 1] is the estimate
  saying "no bias wander identified" (the wander is only bounded); it is counted as containing 1 and shown apart.
  The in-motion estimate shares one white factor and one wander per sensor group (gyro, accel), so the three
  axes of a group of one estimate carry the same interval.

The motion law is ``none`` (the recording is the IMU error as it is, moving or not, plus the simulator's turn-on
bias per drive): the true in-use factors are 1, which is what the interval share tests. The drives' own fixes are
RTK-level (``--rtk-sigma``), the GNSS regime adds its noise on top (``noise:1.5,3,1``: meter-level, 1 Hz), as in
``scripts/replay_runs.py``.

Unit k (the k-th recording given) gets seeds ``seed0 + unit_step·(k − 1)`` … ``+ seeds − 1`` (``--unit-step 0``:
every unit drives the same routes, for development only; otherwise at least ``--seeds``, so the units'
trajectories differ). Each unit's folder holds what the command writes (``results.json``, ``report.html``); the
pooled tables go to ``OUT/in_use_replay.md`` and ``.json`` with the wall and CPU time of each unit.

Usage: python scripts/in_use_replay.py REC1.npz REC2.npz ... --out OUT [--seeds 2] [--seed0 4950]
       [--unit-step 10] [--vehicle-drives 2] [--workers 2] [--seed-role dev|report] [--pool-only]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from imunoise.cli.options import sigma_triple

PAIRS = (("in_use", "gmwm"), ("in_use", "static_var"), ("gmwm", "static_var"))
NO_HARM_UPPER = 1.01  # the acceptance's bound on in_use/gmwm
COVER_SHARE = 0.90  # the acceptance's share of unit-axes whose interval contains 1


def _run_unit(rec: str, seeds: list[int], a: argparse.Namespace, out: Path) -> dict:
    """The dense-window evidence of one unit (its folder written as the command would); wall and CPU time."""
    from imunoise.experiments import dense
    from imunoise.experiments.common import imu_noise_kwargs
    from imunoise.experiments.gnss_regimes import parse_gnss
    from imunoise.experiments.report import write_evidence
    from imunoise.online import OnlineConfig

    t0, c0 = time.perf_counter(), os.times()
    _, spec = dense.parse_outages(a.outages)
    scen = {"duration_s": a.duration, "n_stops": a.stops, "motion_noise": "none", "gnss_sigma_m": a.rtk_sigma,
            **imu_noise_kwargs(rec, seeds[0], vehicle_drives=a.vehicle_drives)}
    res = dense.run_sim(seeds, spec=spec, regimes=[parse_gnss(g) for g in a.gnss_regime],
                        noise_seeds=list(range(1, 1 + a.noise_seeds)), methods=tuple(a.methods.split(",")),
                        pairs=[p for p in PAIRS if all(m in a.methods.split(",") for m in p)], workers=a.workers,
                        base=OnlineConfig(latency=a.latency), n_boot=a.bootstrap, boot_seed=0,
                        vehicle_drives=a.vehicle_drives, **scen)
    c1 = os.times()
    res["elapsed_s"] = time.perf_counter() - t0
    res["cpu_s"] = (c1.user - c0.user) + (c1.system - c0.system) + (c1.children_user - c0.children_user) + (
        c1.children_system - c0.children_system)
    res["latency_s"] = a.latency
    res["seed_role"] = a.seed_role
    write_evidence(res, out, title=f"imunoise: in-use carry-over, real-noise replay {Path(rec).name}, "
                   f"{len(seeds)} vehicles of {a.vehicle_drives} drives")
    return res


def pooled_ratios(results: list[dict], labels: list[str], n_boot: int = 2000) -> list[dict]:
    """The paired end-drift entries of :data:`PAIRS` per GNSS regime over every unit's drives, units as clusters."""
    from imunoise.experiments.stats import paired_entry

    out = []
    for g in results[0]["per_window"]:
        vals: dict[str, list] = {}
        units: list[str] = []
        for res, lab in zip(results, labels, strict=True):
            by_m = res["per_window"][g]["drift"]
            for m, drives in by_m.items():
                vals.setdefault(m, []).extend(drives)
            units += [lab] * len(next(iter(by_m.values())))
        for m, b in PAIRS:
            if m in vals and b in vals:
                e = paired_entry(m, b, "drift", vals, 1, units=units, n_boot=n_boot)
                out.append(dict(e, gnss=g))
    return out


def _interval_kind(iv: dict | None, factor: str = "white_factor") -> str:
    """'in' / 'out' (a 95 % interval containing 1 or not), 'one' (exactly 1 [1, 1]: no wander identified),
    'bound' (a white factor the data do not identify: no interval, a bound in the part's bounds) or 'none' (not
    given: a K factor without a value has no static K to scale, it is not a bound)."""
    if not iv or iv.get("value") is None:
        return "bound" if iv is not None and factor == "white_factor" else "none"
    ci = iv.get("ci95")
    if ci is None:
        return "bound"
    lo, hi = float(ci[0]), float(ci[1])
    if lo == hi == 1.0:
        return "one"
    return "in" if lo <= 1.0 <= hi else "out"


def coverage(results: list[dict], labels: list[str]) -> dict:
    """The share of unit-axes whose in-use factor interval contains 1 (module docstring), per factor: counts of
    each kind, the strict share (an interval containing 1; a K factor of 1 [1, 1] counted as containing 1), the
    share that also counts the unidentified (bounded) factors, the share of unit-axes all of whose estimates
    contain 1, and a 95 % cluster-t interval of the strict share over the units."""
    from imunoise.experiments.stats import cluster_interval
    from imunoise.imu import AXES

    out = {}
    for factor in ("white_factor", "factor_K"):
        kinds: dict[str, int] = {"in": 0, "out": 0, "one": 0, "bound": 0, "none": 0}
        per_unit_axis: dict[tuple[str, str], list[bool]] = {}
        groups, units, rows = [], [], []
        for res, lab in zip(results, labels, strict=True):
            for key, learned in sorted((res.get("in_use_models") or {}).items()):
                axes = (learned.get("in_motion") or {}).get("axes") or {}
                hits = []
                for ax in AXES:
                    iv = (axes.get(ax) or {}).get(factor)
                    k = _interval_kind(iv, factor)
                    kinds[k] += 1
                    rows.append({"unit": lab, "estimate": key, "axis": ax, "kind": k, "value": (iv or {}).get("value"),
                                 "ci95": (iv or {}).get("ci95")})
                    if k in ("in", "out", "one"):
                        hits.append(k != "out")
                        per_unit_axis.setdefault((lab, ax), []).append(k != "out")
                if hits:
                    groups.append(np.array(hits, dtype=float))
                    units.append(lab)
        given = kinds["in"] + kinds["out"] + kinds["one"]
        strict = (kinds["in"] + kinds["one"]) / given if given else None
        lenient_n = given + kinds["bound"]
        ci = cluster_interval(groups, units=units)["ci"] if len(set(units)) >= 2 else [None, None]
        out[factor] = {
            "counts": kinds, "given": given, "share_contains_1": strict, "share_ci95_units": ci,
            "share_counting_bounds_as_containing_1": (kinds["in"] + kinds["one"] + kinds["bound"]) / lenient_n
            if lenient_n else None,
            "unit_axes": len(per_unit_axis),
            "share_unit_axes_all_estimates_contain_1": (sum(all(v) for v in per_unit_axis.values())
                                                        / len(per_unit_axis)) if per_unit_axis else None,
            "estimates": rows}
    return out


def _pct(x: float | None) -> str:
    return "–" if x is None else f"{100.0 * x:.1f} %"


def summary_md(results: list[dict], labels: list[str], entries: list[dict], cov: dict, a: argparse.Namespace,
               log: list[dict]) -> str:
    """The pooled tables and the acceptance reading as Markdown."""
    roles = sorted({r.get("seed_role", "dev") for r in results})
    n_veh = sum(len(r.get("seeds", [])) for r in results)
    spans = ", ".join(f"{lab}: {r['seeds'][0]}–{r['seeds'][-1]}" for lab, r in zip(labels, results, strict=True))
    lines = [f"# In-use carry-over on the real noise of {len(results)} units ({', '.join(labels)})", "",
             f"Seeds: {', '.join(roles)}; {n_veh} vehicles of {results[0].get('vehicle_drives')} drives "
             f"({spans});"
             " every method scored on each vehicle's last drive; motion law `none`; clusters: units.", "",
             "## End-of-window drift, paired ratios (units as clusters)", "",
             "| GNSS | method / baseline | ratio [95 % CI] | units | drives | windows | verdict |",
             "|---|---|---|---|---|---|---|"]
    for e in entries:
        lo, hi = e["ci"]
        ci = "–" if lo is None else f"{e['ratio']:.3f} [{lo:.3f}, {hi:.3f}]"
        lines.append(f"| {e['gnss']} | {e['method']} / {e['baseline']} | {ci} | {e['n_clusters']} | {e['n_drives']} | "
                     f"{e['n_windows']} | {'significant' if e['significant'] else 'not significant'} |")
    lines += ["", "## Estimated in-use factors: does the 95 % interval contain 1 (the truth under law `none`)?", "",
              "| factor | estimates with an interval | contain 1 | of which 1 [1, 1] (no wander identified, counted "
              "as containing 1) | exclude 1 | not identified (bound only) | share containing 1 [95 % CI over units] "
              "| share counting the bounds as containing 1 | unit-axes all of whose estimates contain 1 |",
              "|---|---|---|---|---|---|---|---|---|"]
    for f, c in cov.items():
        k = c["counts"]
        lo, hi = c["share_ci95_units"]
        ci = "" if lo is None else f" [{_pct(max(lo, 0.0))}, {_pct(min(hi, 1.0))}]"
        lines.append(f"| {f} | {c['given']} | {k['in'] + k['one']} | {k['one']} | {k['out']} | {k['bound']} | "
                     f"{_pct(c['share_contains_1'])}{ci} | {_pct(c['share_counting_bounds_as_containing_1'])} | "
                     f"{_pct(c['share_unit_axes_all_estimates_contain_1'])} of {c['unit_axes']} |")
    up = next((e["ci"][1] for e in entries if (e["method"], e["baseline"]) == ("in_use", "gmwm")
               and e["ci"][1] is not None), None)
    share = cov["white_factor"]["share_contains_1"]
    share_k = cov["factor_K"]["share_contains_1"]
    lines += ["", "## Acceptance reading", "",
              f"- in_use/gmwm upper bound {'–' if up is None else f'{up:.3f}'} ≤ {NO_HARM_UPPER}: "
              f"{'met' if up is not None and up <= NO_HARM_UPPER else 'not met'}.",
              f"- white-factor intervals containing 1: {_pct(share)} ≥ {COVER_SHARE:.0%}: "
              f"{'met' if share is not None and share >= COVER_SHARE else 'not met'} (bounds not counted).",
              f"- K-factor intervals containing 1, where given: {_pct(share_k)} ≥ {COVER_SHARE:.0%}: "
              f"{'met' if share_k is not None and share_k >= COVER_SHARE else 'not met'} (1 [1, 1] counted as "
              "containing 1; bounds not counted).",
              "- The three axes of a sensor group share one estimated interval (the estimate is per group).", "",
              "## Cost", "", "| unit | vehicles | wall [s] | CPU [s] |", "|---|---|---|---|"]
    lines += [f"| {r['run']} | {r['vehicles']} | {r['wall_s']} | {r['cpu_s']} |" for r in log]
    lines += ["", f"Settings: {a.duration:g} s drives, {a.stops} stops, outages {a.outages}, GNSS "
              f"{', '.join(a.gnss_regime)} on fixes of σ {a.rtk_sigma} m, {a.noise_seeds} noise seed(s), latency "
              f"{a.latency:g} s, methods {a.methods}, workers {a.workers}."]
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("recordings", nargs="+", help="one static recording (.npz) per IMU unit")
    p.add_argument("--out", required=True, help="output folder (one sub-folder per unit, the pooled tables)")
    p.add_argument("--seeds", type=int, default=2, help="vehicles per unit (default 2)")
    p.add_argument("--seed0", type=int, default=4950, help="first seed of the first unit (default 4950)")
    p.add_argument("--unit-step", type=int, default=10,
                   help="seed offset between units (default 10; 0: the same routes for every unit, development)")
    p.add_argument("--vehicle-drives", type=int, default=2, help="drives per vehicle, scored on the last (default 2)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--seed-role", choices=("dev", "report"), default="dev")
    p.add_argument("--duration", type=float, default=600.0, help="drive length [s] (default 600)")
    p.add_argument("--stops", type=int, default=4, help="stops per drive (default 4)")
    p.add_argument("--outages", default="dense:60:20")
    p.add_argument("--gnss-regime", action="append", default=None, help="GNSS regime (default noise:1.5,3,1)")
    p.add_argument("--noise-seeds", type=int, default=1, help="GNSS noise seeds (default 1)")
    p.add_argument("--methods", default="plain,static_var,gmwm,in_use")
    p.add_argument("--latency", type=float, default=0.5, help="model latency [s] (default 0.5)")
    p.add_argument("--rtk-sigma", type=sigma_triple, default=(0.02, 0.02, 0.05), help="the drives' fixes' σ N,E,D [m]")
    p.add_argument("--bootstrap", type=int, default=2000)
    p.add_argument("--pool-only", action="store_true", help="pool the unit folders already in --out, run nothing")
    a = p.parse_args(argv)
    a.gnss_regime = a.gnss_regime or ["noise:1.5,3,1"]
    if a.unit_step != 0 and a.unit_step < a.seeds:
        p.error(f"--unit-step {a.unit_step} < --seeds {a.seeds}: units would share some routes; give 0 (all the "
                f"same, development) or at least {a.seeds}")
    if "in_use" not in a.methods.split(",") or a.vehicle_drives < 2:
        p.error("the carry-over evidence needs --methods with in_use and --vehicle-drives 2 or more")
    if a.seed_role == "report" and not a.pool_only:  # a report label must be true (the command's own rule)
        from imunoise.experiments.report_tables import seed_role_problem

        why = seed_role_problem(sim=True, seeds=range(a.seed0, a.seed0 + a.unit_step * len(a.recordings) + a.seeds))
        if why:
            p.error(f"--seed-role report: {why}")
    root = Path(a.out)
    root.mkdir(parents=True, exist_ok=True)
    results, labels, log = [], [], []
    for k, rec in enumerate(a.recordings):
        seeds = list(range(a.seed0 + a.unit_step * k, a.seed0 + a.unit_step * k + a.seeds))
        name = Path(rec).stem.split("_")[-1]
        folder = root / name
        if a.pool_only:
            res = json.loads((folder / "results.json").read_text())
        else:
            res = _run_unit(rec, seeds, a, folder)
        log.append({"run": name, "recording": Path(rec).name, "seeds": [seeds[0], seeds[-1]], "vehicles": len(seeds),
                    "wall_s": round(float(res.get("elapsed_s", 0.0)), 1),
                    "cpu_s": round(float(res.get("cpu_s", 0.0)), 1)})
        print(json.dumps(log[-1]), flush=True)
        results.append(res)
        labels.append(name)
    entries = pooled_ratios(results, labels, a.bootstrap)
    cov = coverage(results, labels)
    md = summary_md(results, labels, entries, cov, a, log)
    (root / "in_use_replay.md").write_text(md + "\n")
    (root / "in_use_replay.json").write_text(json.dumps({"paired": entries, "coverage": cov, "runs": log,
                                                         "labels": labels}, indent=1, default=float))
    print(md)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
