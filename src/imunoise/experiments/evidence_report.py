"""The evidence section of the experiments' reports (docs/guide/theory.rst, 'Experiments'): paired drift ratios on dense
outage windows with their CIs, as tables, figures and ``report.html``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from imunoise.experiments.common import METHOD_LABELS
from imunoise.experiments.report_tables import (
    DEMO_HEADS,
    seed_role_text,
    write_csv,
    write_results,
)
from imunoise.report import Report, fmt

__all__ = ["PAIRED_HEADS", "evidence_headline_rows", "evidence_section", "paired_rows", "write_evidence"]


def _ci_text(e: dict | None) -> str:
    return "" if e is None else f"[{fmt(e['ci'][0], 3)}, {fmt(e['ci'][1], 3)}]"


def evidence_headline_rows(evidence: dict) -> list[list[Any]]:
    """The powered headline: per GNSS regime and method, the paired end-drift ratio against ``plain`` and
    against ``static_var`` with their 95 % CIs (:func:`imunoise.experiments.dense.paired_list`).

    One row per (regime, method ≠ plain); a ratio < 1 means less drift than the baseline. Pairs that were not
    run (e.g. no ``static_var``) are left empty."""
    from imunoise.experiments.dense import significance_text

    by = {(e.get("gnss", ""), e["method"], e["baseline"]): e for e in evidence.get("paired", [])
          if e["metric"] == "drift"}
    rows = []
    for g in evidence.get("gnss", []):
        for m in evidence.get("methods", []):
            if m == "plain":
                continue
            vp, vs = by.get((g, m, "plain")), by.get((g, m, "static_var"))
            if vp is None and vs is None:
                continue
            ref = vp or vs
            rows.append([g, m, None if vp is None else vp["ratio"], _ci_text(vp),
                         None if vs is None else vs["ratio"], _ci_text(vs), ref["n_windows"], ref.get("n_independent"),
                         "" if vp is None else significance_text(vp)])
    return rows


def evidence_section(rep: Report, evidence: dict, out: Path) -> None:
    """The headline section of a report: the paired ratios of ``evidence`` as a table, a CSV and a figure."""
    p = evidence["protocol"]
    rep.heading("Headline: paired drift ratios on dense outage windows", 2)
    rep.paragraph(
        f"Windows of {p['length_s']:g} s opened every {p['step_s']:g} s after {p['lead_s']:g} s of GNSS-aided "
        f"driving ({evidence['n_windows']} windows, {evidence['n_independent']} of them share no data, "
        f"{evidence['n_drives']} drive); each window is one run without GNSS from the same aided state. Ratio = "
        "geometric mean over the windows of the method's end drift over the baseline's (noise seeds averaged per "
        "window); 95 % CI: one drive, so a fixed-b t over its windows (Bartlett long-run variance with bandwidth n, "
        "Kiefer–Vogelsang 2002; critical value calibrated on an AR(1) fitted to the windows); "
        "one drive: the interval describes this drive's windows only. A method is better only where the CI "
        "excludes 1. GNSS regimes: rtk = as "
        "recorded; noise:H,V,RATE = the RTK fixes thinned to RATE Hz with white noise of σ H m horizontal and "
        "V m vertical (the paper's meter-level regime)."
    )
    rows = evidence_headline_rows(evidence)
    rep.table(DEMO_HEADS, rows, "end drift ratio < 1: less drift than the baseline")
    write_csv(out / "paired_headline.csv", DEMO_HEADS, rows)
    from imunoise.experiments import plots

    rep.figure(plots.paired_figure(evidence.get("paired", []), out / "paired.png"),
               "the same ratios: filled = the CI excludes 1 (significant), hollow = it does not")



PAIRED_HEADS = ["GNSS", "method", "baseline", "metric", "ratio", "95 % CI", "n_windows", "n_independent",
                "n_drives", "verdict"]


def _scope_note(results: dict) -> str:
    scopes = {e.get("scope") for e in results.get("paired", []) if e.get("scope")}
    return "".join(f" {sc[0].upper()}{sc[1:]}." for sc in sorted(scopes))


def paired_rows(results: dict) -> list[list[Any]]:
    """Rows of the paired table (headline of the dense-window evidence)."""
    from imunoise.experiments.dense import significance_text

    rows = []
    for e in results.get("paired", []):
        rows.append([e.get("gnss", ""), e["method"], e["baseline"], e["metric"], e["ratio"],
                     _ci_text(e), e["n_windows"], e.get("n_independent"), e["n_drives"],
                     significance_text(e)])
    return rows


NEES_HEADS = ["GNSS", "method", "share inside [%]", "95 % CI [%]", "mean NEES", "epochs", "drives"]


def nees_rows(results: dict) -> list[list]:
    """The NEES table (:func:`imunoise.experiments.nees.nees_summary` per regime and method): shares in %."""
    rows = []
    for g, per in (results.get("nees") or {}).items():
        for m, s in per.items():
            if s.get("share_inside") is None:
                continue
            lo, hi = s["ci95"]
            rows.append([g, m, f"{100 * s['share_inside']:.1f}", f"{100 * lo:.1f}-{100 * hi:.1f}",
                         f"{s['mean_nees']:.3g}", s["epochs"], s["drives"]])
    return rows


def write_evidence(results: dict, out: Path, *, title: str) -> Path:
    """Report of the dense-window evidence (:mod:`imunoise.experiments.dense`): the paired log-ratio table is
    the headline; the per-method means and the official-windows table follow as the paper-style view."""
    from imunoise.experiments.dense import LABELS as DENSE_LABELS

    out.mkdir(parents=True, exist_ok=True)
    p = results["protocol"]
    rep = Report(title)
    rep.paragraph(seed_role_text(results))
    rep.paragraph(
        f"Dense outage protocol {p['outages']}: windows of {p['length_s']:g} s opened every {p['step_s']:g} s "
        f"after {p['lead_s']:g} s of GNSS-aided driving; each method runs once with GNSS everywhere and, at each "
        "window start, a copy of the navigator continues without GNSS through the window (= a full run with that "
        f"window's GNSS removed). {results['n_windows']} windows on {results['n_drives']} drive(s), "
        f"{results['n_independent']} of them share no data. Metrics: drift = horizontal error at the window's "
        "end; rms = horizontal RMS inside the window; aided_rms = horizontal RMS of the GNSS-aided run over the "
        "window (paper Table 5's metric). Ratio = geometric mean of the paired ratios method/baseline over the "
        "windows (log-ratios averaged over GNSS noise seeds first); 95 % CI = exp(mean ± t·SE) with the drives "
        "(units above drives when given) as the clusters: with C ≥ 2 clusters the cluster-robust SE and "
        "df = C − 1; with one drive a fixed-b t (Bartlett long-run variance with bandwidth n, Kiefer–Vogelsang "
        "2002; critical value calibrated on an AR(1) fitted to the windows), and the interval describes that "
        "drive's windows only. A method is "
        "better only where the CI excludes 1." + _scope_note(results)
    )
    rep.heading("Paired ratios (headline)", 2)
    rows = paired_rows(results)
    rep.table(PAIRED_HEADS, rows, "ratio < 1: the method's error is smaller than the baseline's")
    write_csv(out / "paired.csv", PAIRED_HEADS, rows)
    from imunoise.experiments import plots

    rep.figure(plots.paired_figure(results.get("paired", []), out / "paired_drift.png"),
               "end-drift ratios: filled = the CI excludes 1 (significant), hollow = it does not")
    if nrows := nees_rows(results):
        rep.heading("Consistency: NEES of position + velocity", 2)
        rep.table(NEES_HEADS, nrows, "share of the GNSS-aided run's 1 Hz epochs (from 60 s after the start) whose "
                  "NEES (6 dof) is inside the two-sided 95 % chi-square band; a consistent filter: about 95 %. "
                  "95 % CI: percentile bootstrap over the drives")
        write_csv(out / "nees.csv", NEES_HEADS, nrows)
    rep.heading("Paper-style view", 2)
    labels = {**METHOD_LABELS, **DENSE_LABELS}
    heads = ["GNSS", "method", "horiz. RMS, aided [m]", "vert. RMS, aided [m]", "mean end drift, dense [m]",
             "mean RMS in window, dense [m]", "mean drift, official windows [m]"]
    srows = []
    for g, s in results["summary"].items():
        for m, r in s.items():
            srows.append([g, f"{m} ({labels.get(m, m)})", r["horizontal_rms_m"], r["vertical_rms_m"],
                          r["mean_end_drift_m"], r["mean_window_rms_m"], r.get("paper_mean_drift_m")])
    rep.table(heads, srows, "arithmetic means (over windows and noise seeds); not a test — see the paired table")
    write_csv(out / "summary.csv", heads, srows)
    pw = results.get("paper_windows") or []
    if pw:
        oheads = ["GNSS", "method"] + [f"#{i + 1} @ {w[0]:.0f}" for i, w in enumerate(pw)] + ["mean"]
        orows = [[g, m, *(r.get("paper_windows_drift_m") or []), r.get("paper_mean_drift_m")]
                 for g, s in results["summary"].items() for m, r in s.items()]
        rep.table(oheads, orows, "the dataset's official windows: end drift [m] (one run per window; 5 windows "
                  "are too few for a conclusion)")
        write_csv(out / "outages.csv", oheads, orows)
    write_results(results, out)
    html, _ = rep.write(out)
    return html
