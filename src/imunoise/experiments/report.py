"""Writers of the experiments' outputs (SPEC §11): ``results.json``, CSV + Markdown tables, figures and one
self-contained ``report.html`` (with ``report.md``)."""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.experiments.common import METHOD_LABELS
from imunoise.io.jsonutil import json_default
from imunoise.report import Report, fmt

__all__ = ["write_results", "headline_rows", "write_online_real", "write_sim", "write_denial_real", "write_evidence",
           "paired_rows", "seed_role_text"]

HEADLINE = ["method", "horizontal RMS [m]", "vertical RMS [m]", "ECEF RMS X/Y/Z [m]", "mean outage-end drift [m]",
            "Δ drift vs plain [%]"]


def _clean(o: Any) -> Any:
    if isinstance(o, dict):
        return {str(k): _clean(v) for k, v in o.items() if not str(k).startswith("_")}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if isinstance(o, np.ndarray):
        return _clean(o.tolist())
    if isinstance(o, (np.floating, float)):
        v = float(o)
        return v if math.isfinite(v) else None
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.bool_,)):
        return bool(o)
    return o


def _short(o: Any) -> Any:
    """Floats rounded for reading: times (≥ 10⁴, GPS seconds) to the ms, the rest to 6 significant digits."""
    if isinstance(o, dict):
        return {k: _short(v) for k, v in o.items()}
    if isinstance(o, list):
        return [_short(v) for v in o]
    if isinstance(o, float):
        return round(o, 3) if abs(o) >= 1e4 else float(f"{o:.6g}")
    return o


def write_results(results: dict, out: Path) -> Path:
    """``results.json`` without the in-memory objects (keys starting with ``_``)."""
    p = out / "results.json"
    p.write_text(json.dumps(_clean(results), indent=1, default=json_default))
    return p


def _write_csv(path: Path, headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> Path:
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(headers)
        for r in rows:
            w.writerow([fmt(c) if not isinstance(c, str) else c for c in r])
    return path


def headline_rows(results: dict) -> list[list[Any]]:
    """Rows of the headline table: method (label), RMS, ECEF RMS, mean drift, % change vs plain."""
    from imunoise.experiments.denial import LABELS as DENIAL

    labels = DENIAL if results.get("experiment") == "denial" else METHOD_LABELS
    m = results["methods"]
    plain = m.get("plain", {}).get("mean_outage_end_horizontal_m")
    rows = []
    for name, r in m.items():
        d = r.get("mean_outage_end_horizontal_m")
        imp = None if (plain is None or d is None or name == "plain") else 100.0 * (d / plain - 1.0)
        ecef = "/".join(fmt(x, 3) for x in (r.get("ecef_rms_m") or []))
        label = labels.get(name, name)
        shown = label if label.startswith(name) else f"{name} ({label})"  # no "plain (plain LC …)"
        rows.append([shown, r.get("horizontal_rms_m"), r.get("vertical_rms_m"),
                     ecef, d, imp])
    return rows


def _outage_rows(results: dict) -> tuple[list[str], list[list[Any]]]:
    wins = results.get("windows") or []
    heads = ["method"] + [f"#{i + 1} @ {w[0]:.0f}" for i, w in enumerate(wins)] + ["mean"]
    rows = []
    for name, r in results["methods"].items():
        ends = r.get("outage_end_horizontal_m") or []
        rows.append([name] + list(ends) + [r.get("mean_outage_end_horizontal_m")])
    kf = results.get("kfgins_outage_end_horizontal_m")
    if kf:
        rows.append(["KF-GINS (C++, README)"] + list(kf) + [float(np.mean(kf))])
    return heads, rows


def _headline(report: Report, results: dict, out: Path, caption: str) -> list[list[Any]]:
    rows = headline_rows(results)
    report.table(HEADLINE, rows, caption)
    _write_csv(out / "headline.csv", HEADLINE, rows)
    return rows


def _timing(report: Report, results: dict) -> None:
    t = results.get("timing") or {}
    rows = []
    if t.get("identification_s") is not None:
        rows.append(["structure identification (all 6 axes)", t["identification_s"]])
    if t.get("identification_per_axis_s"):
        rows.append(["identification, slowest axis", max(t["identification_per_axis_s"])])
    if t.get("identification_max_axis_s") is not None:
        rows.append(["identification, slowest axis (all seeds)", t["identification_max_axis_s"]])
    if t.get("refit_s"):
        rows.append(["refits (6 axes) per stop", ", ".join(fmt(x, 3) for x in t["refit_s"][:12])])
    rma = t.get("refit_max_axis_s")
    if rma:
        rows.append(["refit, slowest axis", max(rma) if isinstance(rma, list) else rma])
    if rows:
        report.table(["modelling step", "time [s]"], rows, "modelling time inside the online run (paper Table 6: "
                     "1.4 min identification, 1.9–2.4 s re-estimation)")


DEMO_HEADS = ["GNSS", "method", "drift vs plain", "95 % CI", "drift vs static_var", "95 % CI ", "n_windows",
              "n_independent", "verdict vs plain"]


SEED_ROLES = {
    "dev": "development seeds (the methods were designed or tuned on runs like this one; not evidence)",
    "report": "report seeds (fresh seeds, run once for this method version)",
}


def seed_role_text(results: dict) -> str:
    """The sentence naming the run's seed role (``results["seed_role"]``, ``--seed-role``; issue 21 §4)."""
    role = results.get("seed_role") or "dev"
    return f"Seeds: {role} — {SEED_ROLES.get(role, role)}."


def replay_text(scen: dict) -> str:
    """The sentence on the IMU errors' origin when a real recording is replayed (``--imu-noise``), else ""."""
    path = scen.get("imu_noise")
    if not path:
        return ""
    from imunoise.sim.replay import load_recording

    rec = load_recording(path)
    reserve = scen.get("imu_noise_reserve_s") or 0.0
    return (f"IMU errors: NOT the model above but a real static recording replayed, {path} "
            f"({rec.n / rec.rate_hz:.0f} s at {rec.rate_hz:g} Hz = the simulator's rate, not resampled; its mean "
            "over the whole file removed): "
            f"drive d = seed − {scen.get('imu_noise_first', 0)} uses samples [d·n, (d + 1)·n), no two drives "
            "overlap, stops show the recording at the stop times"
            + (f"; the static recording is its last {reserve:.0f} s, which no drive uses." if reserve else "."))


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


def _evidence_section(rep: Report, evidence: dict, out: Path) -> None:
    p = evidence["protocol"]
    rep.heading("Headline: paired drift ratios on dense outage windows", 2)
    rep.paragraph(
        f"Windows of {p['length_s']:g} s opened every {p['step_s']:g} s after {p['lead_s']:g} s of GNSS-aided "
        f"driving ({evidence['n_windows']} windows, {evidence['n_independent']} of them share no data, "
        f"{evidence['n_drives']} drive); each window is one run without GNSS from the same aided state. Ratio = "
        "geometric mean over the windows of the method's end drift over the baseline's (noise seeds averaged per "
        "window); 95 % CI: one drive, so a circular block bootstrap over its windows with the block chosen from "
        f"the data (Politis–White 2004/2009, at least {p['block']} windows), t with blocks − 1 dof; "
        "one drive: the interval describes this drive's windows only. A method is better only where the CI "
        "excludes 1. GNSS regimes: rtk = as "
        "recorded; noise:H,V,RATE = the RTK fixes thinned to RATE Hz with white noise of σ H m horizontal and "
        "V m vertical (the paper's meter-level regime)."
    )
    rows = evidence_headline_rows(evidence)
    rep.table(DEMO_HEADS, rows, "end drift ratio < 1: less drift than the baseline")
    _write_csv(out / "paired_headline.csv", DEMO_HEADS, rows)
    from imunoise.experiments import plots

    rep.figure(plots.paired_figure(evidence.get("paired", []), out / "paired.png"),
               "the same ratios: filled = the CI excludes 1 (significant), hollow = it does not")


def write_online_real(results: dict, sc: Any, out: Path, *, title: str | None = None,
                      evidence: dict | None = None) -> Path:
    """Report of the online experiment on a real drive (figures from the in-memory objects).

    With ``evidence`` (the results of :func:`imunoise.experiments.dense.run_real` on the same drive) the
    paired dense-window table is the headline and the official-window tables follow as the paper-style view.
    """
    from imunoise.experiments import plots
    from imunoise.experiments.common import static_segments

    out.mkdir(parents=True, exist_ok=True)
    obj = results.get("_objects", {})
    rep = Report(title or f"imunoise: online GMWM on {sc.name}")
    rep.paragraph(seed_role_text(results))
    if evidence is not None:
        _evidence_section(rep, evidence, out)
        (out / "evidence.json").write_text(json.dumps(_clean(evidence), indent=1, default=json_default))
    rep.paragraph(
        "Paper §3.2 (Tables 5–6) on our data. Each method runs the same loosely coupled EKF (SPEC §8) over the "
        "drive; the online GMWM detects stops (Eq. 9/10), identifies the error structure of every axis after "
        "the first ≥ 20 s of static data (GOF, paper Eq. 8, over all 79 sub-models of 4×AR1+DR+WN+QN+RW; the "
        "WVIC variant is gmwm_wvic), re-estimates it after every later stop and hot-swaps it into the filter at the "
        "stop end plus the measured compute time. AV/EM baselines use all static data of the record (hindsight), "
        "as in the paper. The outage runs remove GNSS inside one 60 s window each, from the same start "
        "(README protocol); drift = horizontal error at the last reference epoch in the window. The full-GNSS "
        "RMS is a residual against the same RTK that aids the filter (no independent truth on this drive)."
    )
    if evidence is None:
        rep.heading("Headline", 2)
        _headline(rep, results, out, "all methods (lengths in m; Δ < 0 is better than plain)")
    else:
        rep.heading("Paper-style view: the dataset's five official outage windows", 2)
        rep.paragraph("Five windows cannot rank methods (the smallest two-sided Wilcoxon p with n = 5 is 0.0625): "
                      "this is the paper's Table 5 view, not a test. RTK GNSS as recorded.")
        _headline(rep, results, out, "all methods (lengths in m; Δ < 0 is better than plain; n = 5 windows)")
    heads, rows = _outage_rows(results)
    rep.table(heads, rows, "horizontal drift at the end of each 60 s outage [m]")
    _write_csv(out / "outages.csv", heads, rows)
    _timing(rep, results)
    sec = results.get("sections")
    if sec:
        srows = []
        upd = sec.get("updates", [])
        for row in sec["rows"]:
            for s in row["sections"]:
                if s.get("n", 0) == 0:
                    continue
                srows.append([row["method"], f"{s['t0'] - sc.init.t:.0f}–{s['t1'] - sc.init.t:.0f}",
                              *s["ecef_rms_m"], s["horizontal_rms_m"], s["vertical_rms_m"]])
        rep.table(["method", "section [s from start]", "X RMS", "Y RMS", "Z RMS", "horiz. RMS", "vert. RMS"], srows,
                  "RMS per section between long stops (paper Table 6; full GNSS, m)")
        _write_csv(out / "sections.csv", ["method", "section", "X", "Y", "Z", "horizontal", "vertical"], srows)
        if upd:
            rep.table(["job", "stop end [s]", "in filter at [s]", "static data [s]", "compute [s]"],
                      [[u["kind"], u["t_stop"] - sc.init.t,
                        None if u["t_effect"] is None else u["t_effect"] - sc.init.t, u["static_s"], u["elapsed_s"]]
                       for u in upd], "modelling after each stop")
    figs = []
    g = next((m for m in ("gmwm", "gmwm_wvic", "gmwm_zupt") if m in obj), None)
    try:
        segs, det = static_segments(sc)
        p = plots.detection_figure(sc.imu.t, det, out / "detection.png", ref=sc.ref, static_truth=sc.static_truth)
        figs.append((p, "static detection: Eq. 9 statistic, adaptive threshold, detected stops, RTK speed (Fig. 8)"))
    except Exception as exc:  # noqa: BLE001 - a figure must not stop the report
        rep.paragraph(f"(detection figure skipped: {exc})")
    traj_methods = [m for m in ("plain", "av", "em", "gmwm", "gmwm_zupt") if m in obj]
    figs.append((plots.trajectory_figure(sc, obj, out / "trajectory.png", traj_methods),
                 "reference and the trajectories inside the outage windows (Fig. 10)"))
    figs.append((plots.error_figure(sc, obj, out / "errors.png", traj_methods),
                 "horizontal error in the outages and ECEF residuals with full GNSS (Fig. 11)"))
    if g:
        full = obj[g]["_full"]
        figs.append((plots.timeline_figure(full, out / "timeline.png", sc.init.t),
                     "event timeline: static segments, gate, model updates"))
    for p, cap in figs:
        rep.figure(p, cap)
    if g:
        full = obj[g]["_full"]
        rep.heading("Online GMWM models (final, per axis)", 2)
        rep.table(["axis", "GMWM structure", "GOF", "filter model (after mapping)"],
                  [[a, str(f.model) if f else "–", f.objective if f else None, str(m)]
                   for a, f, (m, _) in zip(plots.AXES, full.fits, full.final_models)])
        for p in plots.wv_figures(full.fits, out, "wv"):
            rep.figure(p, f"{p.stem[3:]}: pooled WV of the static segments with the online GMWM fit")
        if "av" in obj and "_fits" in obj["av"]:
            rep.figure(plots.av_figures(obj["av"]["_fits"], full.fits, out), "Allan deviation with AV and GMWM models")
        rep.heading("Event log", 2)
        lines = [json.dumps(_short(_clean(e)), ensure_ascii=False) for e in full.events
                 if e["event"] not in ("gate_open", "gate_closed")]
        n_gate = sum(e["event"] == "gate_open" for e in full.events)
        rep.log(lines + [f"({n_gate} gate-open events not shown; all events at full precision in events.jsonl)"])
        full.write_events(out / "events.jsonl")
    write_results(results, out)
    html, _ = rep.write(out)
    return html


def write_denial_real(results: dict, sc: Any, out: Path) -> Path:
    from imunoise.experiments import plots

    out.mkdir(parents=True, exist_ok=True)
    obj = results.get("_objects", {})
    rep = Report(f"imunoise: GNSS-denial experiment on {sc.name}")
    rep.paragraph(seed_role_text(results))
    rep.paragraph(
        "Paper §3.1 (Table 1). The drive has no separate static recording, so the models come from all its "
        f"static segments ({results.get('static_s', 0):.0f} s): the three best by GOF of the selection over the "
        "complete model, the best by WVIC and the AV model; each drives the EKF (fixed model) through the 60 s "
        "outages, one run per window from the same start."
    )
    _headline(rep, results, out, "all models (m)")
    heads, rows = _outage_rows(results)
    rep.table(heads, rows, "horizontal drift at the end of each 60 s outage [m] (Table 1)")
    _write_csv(out / "outages.csv", heads, rows)
    rep.table(["model", *plots.AXES], [[n, *ms] for n, ms in results.get("models", {}).items()], "structures")
    _timing(rep, results)
    runs = obj.get("runs", {})
    meth = [m for m in results["methods"] if m in runs]
    from imunoise.experiments.denial import LABELS

    rep.figure(plots.trajectory_figure(sc, runs, out / "trajectory.png", meth, LABELS), "trajectories in the outages")
    rep.figure(plots.error_figure(sc, runs, out / "errors.png", meth, LABELS), "errors")
    models = obj.get("models")
    if models:
        for p in plots.wv_figures(models["gmwm"], out, "wv"):
            rep.figure(p, f"{p.stem[3:]}: best GMWM model by GOF")
        rep.figure(plots.av_figures(models["av"], models["gmwm"], out), "Allan deviation, AV and GMWM models")
    write_results(results, out)
    html, _ = rep.write(out)
    return html


def write_sim(results: dict, out: Path, *, title: str) -> Path:
    """Report of a Monte Carlo (online or denial) on the simulator."""
    from imunoise.experiments import plots

    out.mkdir(parents=True, exist_ok=True)
    methods = list(results["methods"])
    rep = Report(title)
    rep.paragraph(seed_role_text(results))
    n = len(results["seeds"])
    scen = results.get("scenario") or {}
    motion = scen.get("motion_noise", "drive0708")
    rep.paragraph(
        f"Monte Carlo over {n} simulated urban drives (SPEC §10; IMU truth 3*AR1+WN+RW per axis, the simulator's "
        f"{scen.get('imu_models', 'paper')} preset, plus turn-on biases; motion law of the errors: {motion} "
        "(imunoise.sim.motion); stops of 5–90 s; 60 s outages, all "
        "windows removed in one run). Values are means over seeds; the differences are paired per seed with "
        "Student-t 95 % confidence intervals."
    )
    if scen.get("imu_noise"):
        rep.paragraph(replay_text(scen))
    _headline(rep, results, out, f"means over {n} seeds (m; Δ < 0 better than plain)")
    drows = []
    for name, d in results["differences"].items():
        for ref, dd in d.items():
            for key, c in dd.items():
                drows.append([name, ref, key, c["mean_diff"], f"[{fmt(c['ci'][0])}, {fmt(c['ci'][1])}]",
                              c["rel_pct"], f"[{fmt(c['rel_ci_pct'][0])}, {fmt(c['rel_ci_pct'][1])}]",
                              "yes" if c["excludes_zero"] else "no"])
    dh = ["method", "vs", "metric", "mean diff [m]", "95 % CI [m]", "change [%]", "95 % CI [%]", "CI excludes 0"]
    rep.table(dh, drows, "paired differences to plain and AV")
    _write_csv(out / "differences.csv", dh, drows)
    heads, rows = _outage_rows(results)
    rep.table(heads, rows, "mean drift at the end of each outage window [m] (window k of each seed)")
    _write_csv(out / "outages.csv", heads, rows)
    _timing(rep, results)
    rep.figure(plots.mc_figure(results, out / "montecarlo.png", methods), "per-seed distributions")
    ex = results.get("_objects", {}).get("example")
    if ex and ex.get("fits"):
        for p in plots.wv_figures(ex["fits"], out, "wv"):
            rep.figure(p, f"{p.stem[3:]}: GMWM fit (seed {results['seeds'][0]})")
    write_results(results, out)
    html, _ = rep.write(out)
    return html


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
        "df = C − 1; with one drive a circular block bootstrap whose block is chosen from the data "
        f"(Politis–White 2004/2009, at least {p['block']} windows; {p['n_boot']} replicates, seed "
        f"{p['boot_seed']}), df = blocks − 1, and the interval describes that drive's windows only. A method is "
        "better only where the CI excludes 1." + _scope_note(results)
    )
    rep.heading("Paired ratios (headline)", 2)
    rows = paired_rows(results)
    rep.table(PAIRED_HEADS, rows, "ratio < 1: the method's error is smaller than the baseline's")
    _write_csv(out / "paired.csv", PAIRED_HEADS, rows)
    from imunoise.experiments import plots

    rep.figure(plots.paired_figure(results.get("paired", []), out / "paired_drift.png"),
               "end-drift ratios: filled = the CI excludes 1 (significant), hollow = it does not")
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
    _write_csv(out / "summary.csv", heads, srows)
    pw = results.get("paper_windows") or []
    if pw:
        oheads = ["GNSS", "method"] + [f"#{i + 1} @ {w[0]:.0f}" for i, w in enumerate(pw)] + ["mean"]
        orows = [[g, m, *(r.get("paper_windows_drift_m") or []), r.get("paper_mean_drift_m")]
                 for g, s in results["summary"].items() for m, r in s.items()]
        rep.table(oheads, orows, "the dataset's official windows: end drift [m] (one run per window; 5 windows "
                  "are too few for a conclusion)")
        _write_csv(out / "outages.csv", oheads, orows)
    write_results(results, out)
    html, _ = rep.write(out)
    return html
