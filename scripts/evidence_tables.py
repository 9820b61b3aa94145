"""Markdown tables of a dense-window evidence run (``imunoise experiment online --outages dense:...``).

Reads ``results.json`` of one or more runs and prints, per run and GNSS regime, the paired geometric-mean
ratios of every method against ``plain`` and ``static_var`` (drift, RMS inside the window, aided RMS) with
their 95 % CIs, **bold** where the CI excludes 1, then the extra pairs asked with ``--pairs``, and, when the run
has ``oracle`` and ``plain``, every method's share of the oracle's log-gain over plain in end drift (issue 13,
acceptance 1) with its paired bootstrap CI. Used for the tables in docs/acceptance/.

    python scripts/evidence_tables.py out/evidence/results.json [more/results.json ...]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from imunoise.experiments.stats import drive_log_ratios, gain_share

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
                 f"independent, protocol {res['protocol']['outages']}; scenario {res.get('scenario', '')}")
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


def main(paths: list[str]) -> int:
    if not paths:
        print(__doc__.strip().splitlines()[-1].strip(), file=sys.stderr)
        return 2
    for p in paths:
        res = json.loads(Path(p).read_text())
        print(f"### {p}\n")
        print(tables(res))
        print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
