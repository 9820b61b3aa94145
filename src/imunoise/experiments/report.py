"""Writers of the experiments' outputs (docs/guide/theory.rst, 'Experiments'): ``results.json``, CSV + Markdown tables,
figures and one self-contained ``report.html`` (with ``report.md``).

The result files and table rows: :mod:`imunoise.experiments.report_tables`; the evidence section and report:
:mod:`imunoise.experiments.evidence_report` (both re-exported here)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from imunoise.experiments.evidence_report import (
    PAIRED_HEADS,  # noqa: F401 - kept importable from here
    evidence_headline_rows,  # noqa: F401 - imported from here by the demo
    evidence_section,
    paired_rows,
    write_evidence,
)
from imunoise.experiments.report_tables import (
    DEMO_HEADS,  # noqa: F401 - imported from here by the demo
    HEADLINE,
    SEED_ROLES,  # noqa: F401 - kept importable from here
    clean_json,
    headline_rows,
    outage_rows,
    seed_role_text,
    short_floats,
    write_csv,
    write_results,
)
from imunoise.io.jsonutil import json_default
from imunoise.report import Report, fmt

__all__ = ["write_results", "headline_rows", "write_online_real", "write_sim", "write_denial_real", "write_evidence",
           "paired_rows", "seed_role_text"]


def _headline(report: Report, results: dict, out: Path, caption: str) -> list[list[Any]]:
    rows = headline_rows(results)
    report.table(HEADLINE, rows, caption)
    write_csv(out / "headline.csv", HEADLINE, rows)
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


def replay_text(scen: dict) -> str:
    """The sentence on the IMU errors' origin when a real recording is replayed (``--imu-noise``), else ""."""
    path = scen.get("imu_noise")
    if not path:
        return ""
    from imunoise.sim.replay import load_recording

    rec = load_recording(path)
    reserve = scen.get("imu_noise_reserve_s") or 0.0
    k = int(scen.get("imu_noise_drives", 1))
    layout = (f"drive d = seed − {scen.get('imu_noise_first', 0)} uses samples [d·n, (d + 1)·n)" if k == 1 else
              f"vehicle d = seed − {scen.get('imu_noise_first', 0)} has {k} drives, the j-th (0 = oldest, {k - 1} = "
              f"the scored one) uses samples [(d·{k} + j)·n, (d·{k} + j + 1)·n)")
    return (f"IMU errors: NOT the model above but a real static recording replayed, {path} "
            f"({rec.n / rec.rate_hz:.0f} s at {rec.rate_hz:g} Hz = the simulator's rate, not resampled; its mean "
            f"over the whole file removed): {layout}, no two drives "
            "overlap, stops show the recording at the stop times"
            + (f"; the static recording is its last {reserve:.0f} s, which no drive uses." if reserve else "."))


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
    # the demo's dense windows draw GNSS noise seeds on the same drive: the label names them too
    rep.paragraph(seed_role_text({**results, "noise_seeds": (evidence or {}).get("noise_seeds") or []}))
    if evidence is not None:
        evidence_section(rep, evidence, out)
        (out / "evidence.json").write_text(json.dumps(clean_json(evidence), indent=1, default=json_default))
    rep.paragraph(
        "Paper §3.2 (Tables 5–6) on our data. Each method runs the same loosely coupled EKF "
        "(docs/guide/theory.rst, 'Navigation filter') over the "
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
    heads, rows = outage_rows(results)
    rep.table(heads, rows, "horizontal drift at the end of each 60 s outage [m]")
    write_csv(out / "outages.csv", heads, rows)
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
        write_csv(out / "sections.csv", ["method", "section", "X", "Y", "Z", "horizontal", "vertical"], srows)
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
                   for a, f, m in zip(plots.AXES, full.fits, full.final_models)])
        for p in plots.wv_figures(full.fits, out, "wv"):
            rep.figure(p, f"{p.stem[3:]}: pooled WV of the static segments with the online GMWM fit")
        if "av" in obj and "_fits" in obj["av"]:
            rep.figure(plots.av_figures(obj["av"]["_fits"], full.fits, out), "Allan deviation with AV and GMWM models")
        rep.heading("Event log", 2)
        lines = [json.dumps(short_floats(clean_json(e)), ensure_ascii=False) for e in full.events
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
    heads, rows = outage_rows(results)
    rep.table(heads, rows, "horizontal drift at the end of each 60 s outage [m] (Table 1)")
    write_csv(out / "outages.csv", heads, rows)
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
        f"Monte Carlo over {n} simulated urban drives (docs/guide/theory.rst, 'Simulator'; IMU truth 3*AR1+WN+RW per "
        f"axis, the simulator's "
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
    write_csv(out / "differences.csv", dh, drows)
    heads, rows = outage_rows(results)
    rep.table(heads, rows, "mean drift at the end of each outage window [m] (window k of each seed)")
    write_csv(out / "outages.csv", heads, rows)
    _timing(rep, results)
    rep.figure(plots.mc_figure(results, out / "montecarlo.png", methods), "per-seed distributions")
    ex = results.get("_objects", {}).get("example")
    if ex and ex.get("fits"):
        for p in plots.wv_figures(ex["fits"], out, "wv"):
            rep.figure(p, f"{p.stem[3:]}: GMWM fit (seed {results['seeds'][0]})")
    write_results(results, out)
    html, _ = rep.write(out)
    return html
