"""Which stops the online engine models: static precision/recall and outage drift with the stop guard off and on.

    .venv/bin/python scripts/stop_guard_check.py [--seeds 10] [--presets noisy mems] [--workers 2] [--no-real]

Simulator (``simulate_scenario``: 600 s, 4 stops, four 60 s outages; IMU preset ``noisy`` and ``mems``;
moving = static errors, ``motion_noise="none"``), per
drive and guard setting (``none``: every detected stop is modelled; ``nav``: the default guard; ``nav+chi2``:
the guard with the zero-velocity NIS test on unaided samples, ``stop_chi2 = 11.34``, χ²₃ 99 %): epoch
precision and recall of the modelled static samples against the simulator's true stationary mask
(:func:`imunoise.detect.static_metrics`, as the issue-5 detection numbers) in the run with every GNSS fix and
in the run with the outages, and the mean end-of-outage drift of online GMWM (the experiment's ``gmwm``
method) with the plain filter as reference. Pooled over drives: precision = Σ TP / Σ predicted.

Real drive (``data/drive_0708``, the five 60 s outages, one run per outage as ``imunoise experiment online``):
precision/recall against the RTK speed < 0.2 m/s mask and the mean drift of ``gmwm`` with the guard off and
on (``plain`` does not model, so the guard cannot change it). Takes about 15 minutes on two cores.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

import numpy as np

GUARDS = {"none": {"stop_guard": "none"}, "nav": {"stop_guard": "nav"},
          "nav+chi2": {"stop_guard": "nav", "stop_chi2": 11.34}}


def _mask(n: int, segments) -> np.ndarray:
    m = np.zeros(n, dtype=bool)
    for s in segments:
        m[s.i0:s.i1] = True
    return m


def _counts(segments, truth: np.ndarray) -> tuple[int, int, int]:
    """(true positives, predicted, true) static samples of the modelled segments."""
    m = _mask(truth.size, segments)
    return int(np.sum(m & truth)), int(m.sum()), int(truth.sum())


def _sim_job(args: tuple) -> dict:
    seed, preset = args
    from imunoise.experiments.common import evaluate, simulate_scenario
    from imunoise.experiments.online_exp import method_config
    from imunoise.online import OnlineConfig

    logging.getLogger("imunoise").setLevel(logging.ERROR)
    # the paper's premise (moving = static errors, motion_noise "none"): no in-motion vibration gives the car
    # away, the case in which a learned λ0 on a noisy IMU lets smooth cruising pass the IMU-only test
    sc = simulate_scenario(seed, imu_models=preset, motion_noise="none")
    out: dict = {"seed": seed, "preset": preset}
    cfg, _ = method_config("plain", sc)
    out["plain_drift_m"] = evaluate(sc, cfg)["mean_outage_end_horizontal_m"]
    for name, kw in GUARDS.items():
        cfg, _ = method_config("gmwm", sc, OnlineConfig(**kw))
        r = evaluate(sc, cfg, keep=True)
        full, outage = r["_full"], r["_runs"][0][1]
        out[name] = {
            "drift_m": r["mean_outage_end_horizontal_m"],
            "full": _counts(full.segments, sc.static_truth),
            "outages": _counts(outage.segments, sc.static_truth),
            "detected": _counts(full.detected_segments, sc.static_truth),
        }
    return out


def _pr(c) -> tuple[float, float]:
    tp, npred, ntrue = (sum(x[i] for x in c) for i in range(3))
    return (tp / npred if npred else float("nan")), (tp / ntrue if ntrue else float("nan"))


def simulator(seeds: int, presets: list[str], workers: int, out: Path) -> list[str]:
    from imunoise.experiments.common import map_seeds

    cache = out / "sim.json"
    done = json.loads(cache.read_text()) if cache.exists() else []
    have = {(r["seed"], r["preset"]) for r in done}
    for preset in presets:
        jobs = [(s, preset) for s in range(seeds) if (s, preset) not in have]
        done += map_seeds(_sim_job, jobs, workers, progress=lambda s: print(f"  seed {s} done", file=sys.stderr))
        cache.write_text(json.dumps(done))
    rows = ["| preset | guard | precision, every fix | recall, every fix | precision, outages | recall, outages | "
            "GMWM mean outage drift [m] | plain [m] |", "|---|---|---|---|---|---|---|---|"]
    for preset in presets:
        res = [r for r in done if r["preset"] == preset and r["seed"] < seeds]
        plain = float(np.mean([r["plain_drift_m"] for r in res]))
        p, rc = _pr([r["none"]["detected"] for r in res])
        rows.append(f"| {preset} ({len(res)} drives) | detector alone | {p:.3f} | {rc:.3f} | {p:.3f} | {rc:.3f} | | |")
        for name in GUARDS:
            pf, rf = _pr([r[name]["full"] for r in res])
            po, ro = _pr([r[name]["outages"] for r in res])
            drift = float(np.mean([r[name]["drift_m"] for r in res]))
            rows.append(f"| {preset} | {name} | {pf:.3f} | {rf:.3f} | {po:.3f} | {ro:.3f} | {drift:.1f} "
                        f"| {plain:.1f} |")
    return rows


def real(workers: int, out: Path) -> list[str]:
    from imunoise.experiments.common import repo_data_dir
    from imunoise.experiments.online_exp import run_real
    from imunoise.online import OnlineConfig

    cache = out / "real.json"
    done = json.loads(cache.read_text()) if cache.exists() else {}
    rows = ["| drive_0708 | precision (every fix) | recall | detected segments | modelled | dropped pieces | "
            "GMWM mean drift, 5 outages [m] | plain [m] |", "|---|---|---|---|---|---|---|---|"]
    for name in ("none", "nav"):
        if name not in done:
            methods = ("plain", "gmwm") if name == "none" else ("gmwm",)
            res, sc = run_real(str(repo_data_dir()), methods=methods, workers=workers,
                               base=OnlineConfig(**GUARDS[name]))
            full = res["_objects"]["gmwm"]["_full"]
            done[name] = {
                "counts": _counts(full.segments, sc.static_truth),
                "detected": len(full.detected_segments), "modelled": len(full.segments),
                "dropped": len(full.rejected_segments),
                "drift": res["methods"]["gmwm"]["mean_outage_end_horizontal_m"],
                "ends": res["methods"]["gmwm"]["outage_end_horizontal_m"],
                "plain": res["methods"]["plain"]["mean_outage_end_horizontal_m"] if "plain" in res["methods"]
                else done["none"]["plain"],
            }
            cache.write_text(json.dumps(done))
        d = done[name]
        p, rc = _pr([d["counts"]])
        ends = ", ".join(f"{x:.0f}" for x in d["ends"])
        rows.append(f"| guard {name} | {p:.3f} | {rc:.3f} | {d['detected']} | {d['modelled']} | {d['dropped']} | "
                    f"{d['drift']:.1f} ({ends}) | {d['plain']:.1f} |")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--presets", nargs="+", default=["noisy", "mems"])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("out/stop_guard"))
    ap.add_argument("--no-real", action="store_true")
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    lines = simulator(a.seeds, a.presets, a.workers, a.out)
    if not a.no_real:
        lines += [""] + real(a.workers, a.out)
    text = "\n".join(lines)
    (a.out / "stop_guard.md").write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
