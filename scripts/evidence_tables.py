"""Markdown tables of a dense-window evidence run (``imunoise experiment online --outages dense:...``).

Reads ``results.json`` of one or more runs and prints, per run and GNSS regime, the paired geometric-mean
ratios of every method against ``plain`` and ``static_var`` (drift, RMS inside the window, aided RMS) with
their 95 % CIs, **bold** where the CI excludes 1, then the extra pairs asked with ``--pairs``, and, when the run
has ``oracle`` and ``plain``, every method's share of the oracle's log-gain over plain in end drift (issue 13,
acceptance 1) with its paired bootstrap CI. Used for the tables in docs/evidence/.

``--across OTHER.json --pairs A/B[,C/D]`` pairs method A of the (one) run given with method B of run OTHER,
window by window: both runs must hold the same drives and windows (same seeds, scenario and ``--outages``), e.g.
a method added in a later run against a baseline of an earlier one.

    python scripts/evidence_tables.py out/evidence/results.json [more/results.json ...]
    python scripts/evidence_tables.py out/run_a/results.json --across out/run_b/results.json --pairs x/y

``--recompute`` rebuilds every ``paired`` entry from the run's ``per_window`` values with the statistics of this
version (imunoise.experiments.stats), e.g. a one-drive run made before the one-cluster interval changed;
``--interval-json OUT.json`` writes the entries used (recomputed or stored) for later reading.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from imunoise.experiments.stats import drive_log_ratios, gain_share, paired_entry

METRICS = (("drift", "drift"), ("rms", "rms"), ("aided_rms", "aided RMS"))


def _cell(e: dict | None) -> str:
    if e is None:
        return "–"
    lo, hi = e["ci"]
    text = f"{e['ratio']:.3f} [{lo:.3f}, {hi:.3f}]"
    return f"**{text}**" if e.get("significant") else text


def tables(res: dict) -> str:
    """The markdown of one run's ``paired`` list."""
    by = {(e.get("gnss", ""), e["method"], e["baseline"], e["metric"]): e for e in res["paired"]}
    lines = []
    where = f"seeds {res['seeds'][0]}–{res['seeds'][-1]}" if res.get("seeds") else res.get("data", "")
    lines.append(f"{res['n_drives']} drive(s) ({where}), {res['n_windows']} windows, {res['n_independent']} "
                 f"independent, protocol {res['protocol']['outages']}; scenario {res.get('scenario', '')}; "
                 f"seeds: {res.get('seed_role', 'dev')}")
    scopes = sorted({e["scope"] for e in res["paired"] if e.get("scope")})
    lines += [f"({sc})" for sc in scopes]
    for g in res["gnss"]:
        lines += ["", f"#### GNSS {g}", ""]
        heads = ["method"] + [f"{lab} vs {b}" for _, lab in METRICS for b in ("plain", "static_var")]
        lines.append("| " + " | ".join(heads) + " |")
        lines.append("|" + "---|" * len(heads))
        for m in res["methods"]:
            if m == "plain":
                continue
            cells = [_cell(by.get((g, m, b, k))) if m != b else "–"
                     for k, _ in METRICS for b in ("plain", "static_var")]
            lines.append(f"| {m} | " + " | ".join(cells) + " |")
        # the pairs asked with --pairs and every NAME+sf against NAME (the rows above hold the rest)
        extra = sorted({(e["method"], e["baseline"]) for e in res["paired"] if e.get("gnss", "") == g
                        and (e["baseline"] not in ("plain", "static_var") or e["method"] == e["baseline"] + "+sf")})
        if extra:
            lines += ["", "| pair | " + " | ".join(lab for _, lab in METRICS) + " |", "|---|---|---|---|"]
            for a, b in extra:
                lines.append(f"| {a} / {b} | " + " | ".join(_cell(by.get((g, a, b, k))) for k, _ in METRICS) + " |")
        lines += _share_rows(res, g)
    return "\n".join(lines)


def _share_rows(res: dict, g: str) -> list[str]:
    """Each method's share of the oracle's log-gain over plain in end drift, with its 95 % CI."""
    drift = res.get("per_window", {}).get(g, {}).get("drift", {})
    if "oracle" not in drift or "plain" not in drift:
        return []
    proto = res["protocol"]
    ref = [drive_log_ratios(a, b) for a, b in zip(drift["oracle"], drift["plain"], strict=True)]
    out = ["", "| share of the oracle's log-gain over plain (end drift) | share [95 % CI] |", "|---|---|"]
    for m in res["methods"]:
        if m in ("plain", "oracle") or m not in drift:
            continue
        groups = [drive_log_ratios(a, b) for a, b in zip(drift[m], drift["plain"], strict=True)]
        r = gain_share(groups, ref, proto["block"], n_boot=proto.get("n_boot", 2000), seed=proto.get("boot_seed", 0))
        if r["share"] is not None:
            out.append(f"| {m} | {100 * r['share']:.1f} % [{100 * r['ci'][0]:.1f}, {100 * r['ci'][1]:.1f}] |")
    return out


def recompute(res: dict) -> list[dict]:
    """The run's ``paired`` entries computed again from ``per_window`` with the current statistics (same pairs,
    metrics, block, bootstrap size and seed as stored)."""
    proto = res["protocol"]
    out = []
    for e in res["paired"]:
        g, met = e.get("gnss", ""), e["metric"]
        vals = res["per_window"][g][met]
        n = paired_entry(e["method"], e["baseline"], met, {e["method"]: vals[e["method"]],
                                                           e["baseline"]: vals[e["baseline"]]},
                         proto["block"], n_independent_total=res.get("n_independent"),
                         n_boot=proto.get("n_boot", 2000), seed=proto.get("boot_seed", 0))
        out.append(dict(n, gnss=g))
    return out


def cross_pairs(res_a: dict, res_b: dict, pairs: list[tuple[str, str]]) -> list[dict]:
    """``paired`` entries of method A of run ``res_a`` against method B of run ``res_b`` per GNSS regime they share
    and metric; the two runs must have the same windows (else ValueError saying what differs)."""
    if res_a.get("windows") != res_b.get("windows"):
        raise ValueError("the two runs do not hold the same drives and windows (run both with the same --seeds, "
                         "--seed0, scenario and --outages)")
    regimes = [g for g in res_a["gnss"] if g in res_b["gnss"]]
    if not regimes:
        raise ValueError(f"no GNSS regime in common ({res_a['gnss']} vs {res_b['gnss']})")
    proto = res_a["protocol"]
    out = []
    for a, b in pairs:
        for name, res in ((a, res_a), (b, res_b)):
            if name not in res["methods"]:
                raise ValueError(f"method {name!r} is not in its run (methods: {', '.join(res['methods'])})")
        for g in regimes:
            for met, _ in METRICS:
                vals = {"A": res_a["per_window"][g][met][a], "B": res_b["per_window"][g][met][b]}
                e = paired_entry("A", "B", met, vals, proto["block"], n_independent_total=res_a["n_independent"],
                                 n_boot=proto.get("n_boot", 2000), seed=proto.get("boot_seed", 0))
                out.append(dict(e, method=a, baseline=b, gnss=g))
    return out


def cross_table(entries: list[dict]) -> str:
    """The markdown of :func:`cross_pairs`."""
    by = {(e["gnss"], e["method"], e["baseline"], e["metric"]): e for e in entries}
    lines = []
    for g in dict.fromkeys(e["gnss"] for e in entries):
        lines += ["", f"#### GNSS {g}", "", "| pair (across runs) | " + " | ".join(lab for _, lab in METRICS) + " |",
                  "|---|---|---|---|"]
        for a, b in dict.fromkeys((e["method"], e["baseline"]) for e in entries if e["gnss"] == g):
            lines.append(f"| {a} / {b} | " + " | ".join(_cell(by.get((g, a, b, k))) for k, _ in METRICS) + " |")
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("results", nargs="+", help="results.json of dense-window runs")
    p.add_argument("--across", help="results.json of a second run of the same windows: pair across the two runs")
    p.add_argument("--pairs", help="with --across: A/B[,C/D], A of the first run against B of the second")
    p.add_argument("--recompute", action="store_true",
                   help="rebuild the paired entries from per_window with the current statistics")
    p.add_argument("--interval-json", help="write the paired entries shown (one list per results.json) to this file")
    a = p.parse_args(argv)
    if a.across:
        from imunoise.experiments.dense import parse_pairs

        if len(a.results) != 1 or not a.pairs:
            p.error("--across needs exactly one results.json and --pairs A/B")
        try:
            entries = cross_pairs(json.loads(Path(a.results[0]).read_text()), json.loads(Path(a.across).read_text()),
                                  parse_pairs(a.pairs))
        except ValueError as exc:
            p.error(str(exc))
        print(f"### {a.results[0]} against {a.across}")
        print(cross_table(entries))
        return 0
    shown = {}
    for path in a.results:
        res = json.loads(Path(path).read_text())
        if a.recompute:
            res["paired"] = recompute(res)
        shown[path] = res["paired"]
        print(f"### {path}" + (" (paired entries recomputed)" if a.recompute else "") + "\n")
        print(tables(res))
        print()
    if a.interval_json:
        Path(a.interval_json).write_text(json.dumps(shown, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
