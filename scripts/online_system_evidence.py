"""Measure every acceptance number of issue 5 (online system) and write them to one Markdown file.

    .venv/bin/python scripts/online_system_evidence.py --out out/issue5 [--seeds 20] [--reuse]

1. detection on 20 simulated drives (truth: speed < 0.05 m/s and no rotation) and on drive_0708 (RTK speed
   < 0.2 m/s): epoch precision and recall;
2. simulator Monte Carlo of the online experiment (``--seeds`` drives, IMU truth 3*AR1+WN+RW per axis: the
   "paper" preset = gyros of paper Table 4, mems accelerometers; stops 5–90 s, four 60 s outages per drive,
   the first ≥ 60 s after the static start): online GMWM vs AV and plain, paired 95 % CIs, and the oracle
   (the true model in the filter: the ceiling of any model); the same on the "mems" preset; plus the
   GNSS-denial Monte Carlo (2 h static recording per seed);
3. timing inside the online run on the real drive (one process, nothing else of ours running):
   identification per axis, refit per axis, the whole drive × real time;
4. drive_0708: the five outages for plain, AV, EM, online GMWM (+ variants), online GMWM + ZUPT, KF-GINS;
5. streaming API vs batch ``run`` on the real drive: max position difference.

``--reuse`` keeps Monte Carlo results already in OUT (``mc_online/results.json``, ``mc_denial/results.json``).
Takes 15–30 minutes on two cores.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

import numpy as np


def detection(seeds: int) -> list[str]:
    from imunoise.detect import DetectorConfig, detect_static, learn_lambda0, static_metrics
    from imunoise.experiments.common import load_real, repo_data_dir
    from imunoise.sim import DriveConfig, simulate_drive

    rows = []
    tp = npred = ntrue = 0
    per = []
    for s in range(seeds):
        d = simulate_drive(DriveConfig(seed=s), "3*AR1+WN+RW", seed=s)
        g, a = d.imu.rates()
        t = d.imu.t
        lam = learn_lambda0(a[t < t[0] + 10.0])
        det = detect_static(t, a, g, DetectorConfig(lambda0=lam))
        m = static_metrics(det.static, d.static_mask)
        per.append((m["precision"], m["recall"]))
        tp += int(np.sum(det.static & d.static_mask))
        npred += int(det.static.sum())
        ntrue += int(d.static_mask.sum())
    p = np.array(per)
    rows.append(f"| simulator, {seeds} drives (λ0 learned from the first 10 s) | {tp / npred:.4f} | {tp / ntrue:.4f} | "
                f"min per drive: precision {p[:, 0].min():.4f}, recall {p[:, 1].min():.4f} |")
    sc = load_real(repo_data_dir())
    g, a = sc.imu.rates()
    t = sc.imu.t
    det = detect_static(t, a, g, DetectorConfig(lambda0=learn_lambda0(a[t < t[0] + 10.0])))
    m = static_metrics(det.static, sc.static_truth)
    rows.append(f"| drive_0708 vs RTK speed < 0.2 m/s | {m['precision']:.4f} | {m['recall']:.4f} | "
                f"{len(det.segments)} segments, {det.static_time_s:.1f} s static detected, "
                f"{np.sum(sc.static_truth) / sc.rate:.1f} s true |")
    return ["| data | precision | recall | notes |", "|---|---|---|---|", *rows]


def timing() -> tuple[list[str], dict]:
    from imunoise.experiments.common import load_real, repo_data_dir
    from imunoise.online import OnlineConfig, OnlineNavigator

    sc = load_real(repo_data_dir())
    cfg = OnlineConfig(ekf=sc.ekf_config())
    OnlineNavigator(cfg.with_(modelling=False), sc.init, imu_rate_hz=sc.rate).run(sc.imu, sc.gnss)  # warm up
    best = None
    for _ in range(3):
        r = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate).run(sc.imu, sc.gnss)
        if best is None or r.elapsed_s < best.elapsed_s:
            best = r
    t = best.timing
    rtf = sc.duration / best.elapsed_s
    out = {"identification_per_axis_s": t["identification_per_axis_s"], "refit_max_axis_s": t["refit_max_axis_s"],
           "elapsed_s": best.elapsed_s, "realtime_factor": rtf}
    rows = [
        "| quantity | measured | target |", "|---|---|---|",
        f"| identification per axis (6 axes) [s] | {', '.join(f'{x:.2f}' for x in t['identification_per_axis_s'])} "
        f"(max {max(t['identification_per_axis_s']):.2f}) | ≤ 1 |",
        f"| refit, slowest axis per stop [ms] | {', '.join(f'{1e3 * x:.0f}' for x in t['refit_max_axis_s'])} | ≤ 50 |",
        f"| whole drive online ({sc.duration:.0f} s): wall time [s] | {best.elapsed_s:.2f} ({rtf:.0f}× real time) "
        "| ≥ 100× |",
    ]
    return rows, out


def streaming() -> list[str]:
    from imunoise.experiments.common import load_real, repo_data_dir
    from imunoise.nav.earth import llh_to_ecef
    from imunoise.online import OnlineConfig, OnlineNavigator

    sc = load_real(repo_data_dir())
    gnss = sc.gnss.without(sc.windows[:1])
    out = []
    for lat in (0.0, 1.0):
        cfg = OnlineConfig(ekf=sc.ekf_config(), latency=lat, zupt=True)
        batch = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate).run(sc.imu, gnss)
        nav = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate)
        gi = 0
        t = sc.imu.t
        for k in range(t.size):
            while gi < gnss.t.size and gnss.t[gi] <= t[k]:
                nav.push_gnss(gnss.t[gi], gnss.llh[gi], gnss.sigma_ned[gi])
                gi += 1
            nav.push_imu(t[k], sc.imu.dtheta[k], sc.imu.dv[k])
        st = nav.finish()
        d = np.linalg.norm(llh_to_ecef(st.llh) - llh_to_ecef(batch.llh), axis=1).max()
        out.append(f"| drive_0708, outage 1, ZUPT on, latency {lat:g} s | {st.t.size} epochs, "
                   f"{len(st.updates)} model updates | {d:.3g} m |")
    return ["| run | content | max ‖streaming − batch‖ |", "|---|---|---|", *out]


def _rel(c: dict | None) -> str:
    if not c:
        return "–"
    return f"{c['rel_pct']:+.1f} ([{c['rel_ci_pct'][0]:+.1f}, {c['rel_ci_pct'][1]:+.1f}])"


def cached_mc(folder: Path, reuse: bool, label: str, run, title: str) -> dict:
    """A Monte Carlo's results: read from ``folder/results.json`` with ``--reuse``, else ``run()`` and write the
    report there."""
    from imunoise.experiments.report import write_sim

    path = folder / "results.json"
    if reuse and path.exists():
        return json.loads(path.read_text())
    print(label, flush=True)
    res = run()
    write_sim(res, folder, title=title)
    return res


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/issue5")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--reuse", action="store_true")
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING)
    logging.getLogger("imunoise").setLevel(logging.ERROR)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    from imunoise.experiments import denial, online_exp
    from imunoise.experiments.common import repo_data_dir
    from imunoise.experiments.report import headline_rows, write_denial_real, write_online_real
    from imunoise.report import fmt

    md = ["# Issue 5 acceptance numbers", "", f"Measured {time.strftime('%Y-%m-%d %H:%M')} UTC with "
          f"`.venv/bin/python scripts/online_system_evidence.py --out {args.out} --seeds {args.seeds}`.", ""]
    t_all = time.perf_counter()

    print("[5] streaming vs batch", flush=True)
    md += ["## 5. Streaming API = batch run", "", *streaming(), ""]
    print("[3] timing", flush=True)
    rows, _ = timing()
    md += ["## 3. Timing inside the online run (real drive, one process)", "", *rows, ""]
    print("[1] detection", flush=True)
    md += ["## 1. Static detection (epochs inside kept segments)", "", *detection(args.seeds), ""]

    print("[4] real drive, online experiment", flush=True)
    res, sc = online_exp.run_real(str(repo_data_dir()), workers=2)
    write_online_real(res, sc, out / "online_real")
    heads = ["method", "#1", "#2", "#3", "#4", "#5", "mean", "Δ mean vs plain", "horiz. RMS full RTK"]
    plain = res["methods"]["plain"]["mean_outage_end_horizontal_m"]
    rows = []
    for name, m in res["methods"].items():
        e = m["outage_end_horizontal_m"]
        rows.append(f"| {name} | " + " | ".join(f"{x:.1f}" for x in e)
                    + f" | {m['mean_outage_end_horizontal_m']:.1f} | "
                    + f"{100 * (m['mean_outage_end_horizontal_m'] / plain - 1):+.1f} % | {m['horizontal_rms_m']:.4f} |")
    kf = res["kfgins_outage_end_horizontal_m"]
    rows.append("| KF-GINS (README) | " + " | ".join(f"{x:.1f}" for x in kf) + f" | {np.mean(kf):.1f} | "
                f"{100 * (np.mean(kf) / plain - 1):+.1f} % | 0.033 |")
    md += ["## 4. drive_0708: end-of-outage horizontal drift [m], one run per window", "",
           "| " + " | ".join(heads) + " |", "|" + "---|" * len(heads), *rows, "",
           f"Report: `{out / 'online_real' / 'report.html'}`.", ""]
    print("[4b] real drive, denial experiment", flush=True)
    resd, scd = denial.run_real(str(repo_data_dir()))
    write_denial_real(resd, scd, out / "denial_real")
    md += ["### drive_0708, denial (models from the drive's own static data)", "",
           "| method | mean drift [m] | Δ vs plain |", "|---|---|---|"]
    for name, m in resd["methods"].items():
        md.append(f"| {name} | {m['mean_outage_end_horizontal_m']:.1f} | "
                  f"{resd['improvement_vs_plain_pct'].get(name, 0.0):+.1f} % better |"
                  if name != "plain" else f"| plain | {m['mean_outage_end_horizontal_m']:.1f} | – |")
    md.append("")

    seeds = list(range(args.seeds))
    mc = cached_mc(out / "mc_online", args.reuse, f"[2] online Monte Carlo, {len(seeds)} seeds",
                   lambda: online_exp.run_sim(seeds, workers=2),
                   f"imunoise: online experiment, Monte Carlo ({len(seeds)} seeds)")
    md += ["## 2. Simulator Monte Carlo, online experiment", "",
           f"{len(mc['seeds'])} seeds; means over seeds; paired differences with Student-t 95 % CIs.", "",
           "| method | horiz. RMS [m] | vert. RMS [m] | mean outage-end drift [m] |", "|---|---|---|---|"]
    for r in headline_rows(mc):
        md.append(f"| {r[0]} | {fmt(r[1])} | {fmt(r[2])} | {fmt(r[4])} |")
    md += ["", "| comparison | metric | mean diff [m] | 95 % CI [m] | change [%] | 95 % CI [%] | CI excludes 0 |",
           "|---|---|---|---|---|---|---|"]
    for name, d in mc["differences"].items():
        for ref, dd in d.items():
            for key in ("horizontal_rms_m", "mean_outage_end_horizontal_m"):
                c = dd[key]
                md.append(f"| {name} {ref.replace('_', ' ')} | {key} | {c['mean_diff']:.4g} | "
                          f"[{c['ci'][0]:.4g}, {c['ci'][1]:.4g}] | {c['rel_pct']:+.1f} | "
                          f"[{c['rel_ci_pct'][0]:+.1f}, {c['rel_ci_pct'][1]:+.1f}] | "
                          f"{'yes' if c['excludes_zero'] else 'no'} |")
    md.append("")
    mcm = cached_mc(out / "mc_online_mems", args.reuse, f"[2c] online Monte Carlo, mems preset, {len(seeds)} seeds",
                    lambda: online_exp.run_sim(seeds, workers=2, methods=("plain", "av", "gmwm", "oracle"),
                                               imu_models="mems"),
                    f"imunoise: online experiment, mems preset ({len(seeds)} seeds)")
    md += ["### Second scenario: the \"mems\" preset (a sensor close to the plain default)", "",
           "| method | horiz. RMS [m] | mean outage-end drift [m] | drift vs plain [%] (95 % CI) | "
           "RMS vs plain [%] (95 % CI) |", "|---|---|---|---|---|"]
    for name, m in mcm["methods"].items():
        d = mcm["differences"].get(name, {}).get("vs_plain", {})
        cd, cr = d.get("mean_outage_end_horizontal_m"), d.get("horizontal_rms_m")
        md.append(f"| {name} | {fmt(m['horizontal_rms_m'])} | {fmt(m['mean_outage_end_horizontal_m'])} | "
                  f"{_rel(cd)} | {_rel(cr)} |")
    md.append("")
    dn = cached_mc(out / "mc_denial", args.reuse, f"[2b] denial Monte Carlo, {len(seeds)} seeds",
                   lambda: denial.run_sim(seeds, workers=2),
                   f"imunoise: GNSS-denial experiment, Monte Carlo ({len(seeds)} seeds)")
    md += ["### Simulator Monte Carlo, denial experiment (2 h static recording per seed)", "",
           "| method | mean outage-end drift [m] | Δ vs plain [%] (95 % CI) |", "|---|---|---|"]
    for name, m in dn["methods"].items():
        c = dn["differences"].get(name, {}).get("vs_plain", {}).get("mean_outage_end_horizontal_m")
        ci = "–" if not c else f"{c['rel_pct']:+.1f} ([{c['rel_ci_pct'][0]:+.1f}, {c['rel_ci_pct'][1]:+.1f}])"
        md.append(f"| {name} | {fmt(m['mean_outage_end_horizontal_m'])} | {ci} |")
    md += ["", f"Total time {time.perf_counter() - t_all:.0f} s."]
    (out / "ACCEPTANCE.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    sys.exit(main())
