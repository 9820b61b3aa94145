"""Paired ratios with units (sensors) as the clusters, drives nested inside (issue "Evidence that holds
outside our own simulator", §3–§4): one results.json per unit, e.g. one ``experiment online --sim
--imu-noise adis16405_unitK.npz`` run per shared ADIS16405 unit.

Reads dense-window runs (``per_window``: every GNSS regime and metric) or Monte Carlo runs of the online or
denial experiment (``per_seed``: the end drift of each window of each drive) and prints, per GNSS regime and
metric, every method against ``plain`` (and ``static_var`` where run): geometric-mean ratio, 95 % CI with
units as clusters (df = units − 1; :func:`imunoise.experiments.stats.paired_entry` with ``units``), and the
counts. Also the paper-style means per method (over all drives and windows).

Usage: python scripts/unit_tables.py unit1/results.json unit2/results.json ... [--labels u1,u2,...]
       [--pairs gmwm/av,gmwm/em]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from imunoise.experiments.stats import paired_entry


def _drive_values(res: dict) -> dict[tuple[str, str], dict[str, list]]:
    """{(gnss, metric): {method: [per drive: windows or realisations × windows]}} of one run."""
    out: dict[tuple[str, str], dict[str, list]] = {}
    if "per_window" in res:
        for g, mets in res["per_window"].items():
            for met, by_m in mets.items():
                out[(g, met)] = {m: list(v) for m, v in by_m.items()}
        return out
    per = res.get("per_seed") or {}
    gnss = "sim" if res.get("data") == "sim" else "recorded"
    out[(gnss, "drift")] = {m: [r.get("outage_end_horizontal_m") or [] for r in rows] for m, rows in per.items()}
    return out


def pooled(results: list[dict], labels: list[str], n_boot: int = 2000,
           pairs: list[tuple[str, str]] | None = None) -> list[dict]:
    """Paired entries of every method against plain / static_var over all units' drives, units as clusters, then
    the extra ``pairs`` (method, baseline) where both were run (e.g. the paper's gmwm/av, gmwm/em)."""
    keys = set.intersection(*(set(_drive_values(r)) for r in results))
    methods = [m for m in results[0].get("methods", []) if all(m in r.get("methods", []) for r in results)]
    out = []
    for g, met in sorted(keys):
        vals: dict[str, list] = {m: [] for m in methods}
        units: list[str] = []
        for res, lab in zip(results, labels, strict=True):
            dv = _drive_values(res)[(g, met)]
            n_drives = len(dv[methods[0]])
            for m in methods:
                vals[m].extend(dv[m])
            units += [lab] * n_drives
        for base in ("plain", "static_var"):
            if base not in methods:
                continue
            for m in methods:
                if m == base or (m, base) == ("plain", "static_var"):
                    continue
                e = paired_entry(m, base, met, vals, 1, units=units, n_boot=n_boot)
                out.append(dict(e, gnss=g))
        for m, base in pairs or []:
            if m in methods and base in methods and base not in ("plain", "static_var"):
                out.append(dict(paired_entry(m, base, met, vals, 1, units=units, n_boot=n_boot), gnss=g))
    return out


def _mean(drives: list) -> float | None:
    """Mean over drives, realisations and windows (None values left out)."""
    v = [x for d in drives for x in np.ravel(np.array(d, dtype=object)) if x is not None]
    return float(np.mean(np.array(v, dtype=float))) if v else None


def paper_table(results: list[dict], labels: list[str], metric: str = "drift") -> str:
    """The paper-style table (paper Tables 1, 5–6): per GNSS regime and method the mean of ``metric`` [m] over every
    drive and window of every unit, its change against ``plain`` [%], and each unit's own mean (not a test: the
    paired ratios are)."""
    keys = sorted(k for k in set.intersection(*(set(_drive_values(r)) for r in results)) if k[1] == metric)
    methods = [m for m in results[0].get("methods", []) if all(m in r.get("methods", []) for r in results)]
    lines = [f"| GNSS | method | mean {metric} [m] | vs plain [%] | " + " | ".join(labels) + " |",
             "|---|---|---|---|" + "---|" * len(labels)]
    for key in keys:
        per = {m: [_mean(_drive_values(r)[key][m]) for r in results] for m in methods}
        allm = {m: _mean([d for r in results for d in _drive_values(r)[key][m]]) for m in methods}
        for m in methods:
            pct = "–" if m == "plain" or "plain" not in allm else f"{100.0 * (allm[m] / allm['plain'] - 1.0):+.1f}"
            lines.append(f"| {key[0]} | {m} | {allm[m]:.4g} | {pct} | "
                         + " | ".join("–" if x is None else f"{x:.4g}" for x in per[m]) + " |")
    return "\n".join(lines)


def means(results: list[dict]) -> dict[str, float]:
    """Paper-style mean end drift per method over every drive and window of every unit, first GNSS regime (not a
    test)."""
    key = min(k for k in set.intersection(*(set(_drive_values(r)) for r in results)) if k[1] == "drift")
    out = {}
    for m in results[0].get("methods", []):
        v = []
        for res in results:
            for d in _drive_values(res)[key].get(m, []):
                v += [x for x in np.ravel(np.array(d, dtype=object)) if x is not None]
        if v:
            out[m] = float(np.mean(np.array(v, dtype=float)))
    return out


def table(entries: list[dict]) -> str:
    lines = ["| GNSS | metric | method | baseline | ratio [95 % CI] | units | drives | windows | verdict |",
             "|---|---|---|---|---|---|---|---|---|"]
    for e in entries:
        lo, hi = e["ci"]
        ci = "–" if lo is None else f"{e['ratio']:.3f} [{lo:.3f}, {hi:.3f}]"
        verdict = "significant" if e["significant"] else "not significant"
        lines.append(f"| {e['gnss']} | {e['metric']} | {e['method']} | {e['baseline']} | {ci} | {e['n_clusters']} | "
                     f"{e['n_drives']} | {e['n_windows']} | {verdict} |")
    scopes = sorted({e["scope"] for e in entries if e.get("scope")})
    return "\n".join(lines + [f"({s})" for s in scopes])


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("results", nargs="+", help="one results.json per unit")
    p.add_argument("--labels", help="unit labels, comma-separated (default: the folder names)")
    p.add_argument("--bootstrap", type=int, default=2000)
    p.add_argument("--pairs", default="", help="extra comparisons method/baseline,... (e.g. gmwm/av,gmwm/em)")
    a = p.parse_args(argv)
    pairs = [tuple(x.strip().split("/", 1)) for x in a.pairs.split(",") if x.strip()]
    results = [json.loads(Path(f).read_text()) for f in a.results]
    labels = a.labels.split(",") if a.labels else [Path(f).resolve().parent.name for f in a.results]
    if len(labels) != len(results) or len(set(labels)) != len(labels):
        p.error("--labels needs one distinct label per results.json")
    if not set.intersection(*(set(_drive_values(r)) for r in results)):
        p.error("the runs share no GNSS regime and metric (mix of dense-window and Monte Carlo runs, or other "
                "--gnss): give runs of one protocol")
    roles = sorted({r.get("seed_role", "dev") for r in results})
    print(f"{len(results)} units ({', '.join(labels)}); seeds: {', '.join(roles)}\n")
    print("mean end drift per method [m] (all drives and windows, first GNSS regime; not a test): "
          + ", ".join(f"{m} {v:.1f}" for m, v in means(results).items()) + "\n")
    for metric in ("drift", "aided_rms"):
        if any(k[1] == metric for k in set.intersection(*(set(_drive_values(r)) for r in results))):
            print(paper_table(results, labels, metric) + "\n")
    print(table(pooled(results, labels, a.bootstrap, pairs)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
