"""Real-noise replay runs on several recorded IMUs (issue "Evidence that holds outside our own simulator", §3):
per recording (one IMU unit), the online dense-window evidence and the GNSS-denial Monte Carlo on simulated drives
whose IMU errors are the recording's own stretches (:mod:`imunoise.sim.replay`), under centimetre (RTK) and
meter-level GNSS.

It is ``imunoise experiment online|denial --sim --imu-noise FILE.npz`` with one thing the command line does not set:
the simulated fixes' own σ (``DriveConfig.gnss_sigma_m``). The simulator's fixes are meter-level (1 / 1 / 2 m), so
on the simulator ``--gnss-regime rtk`` ("the fixes as recorded") is not RTK; here the drives get RTK-level fixes
(``--rtk-sigma``, default 0.02 / 0.02 / 0.05 m N/E/D) and the meter-level regime adds its noise on top of them
(``noise:1.5,3``: the fixes then say √(0.02² + 1.5²) ≈ 1.5 m and ≈ 3.0 m). The denial experiment has no regime
option: it runs once per GNSS level (``denial_rtk``, ``denial_meter``).

Unit k (the k-th recording given) gets seeds ``seed0 + 10·(k − 1)`` … ``+ seeds − 1`` (other trajectories per unit,
so the units are independent clusters); drive d of a unit replays the recording's samples [d·n, (d + 1)·n), the
denial experiment's static part is the end of the file, which no drive uses. The online and denial runs of a unit
use the same seeds, hence the same drives. Each run writes its folder (``results.json``, ``report.html``) as the
command would; pool them with ``scripts/unit_tables.py``.

Usage: python scripts/replay_runs.py REC1.npz REC2.npz ... --out OUT [--seeds 6] [--seed0 4000000]
       [--which online,denial] [--workers 2] [--seed-role report]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from imunoise.cli.options import sigma_triple

STEP = 10  # seed offset between units


def _online(rec: str, seeds: list[int], a: argparse.Namespace, out: Path) -> None:
    from imunoise.experiments import dense
    from imunoise.experiments.common import imu_noise_kwargs
    from imunoise.experiments.gnss_regimes import parse_gnss
    from imunoise.experiments.report import write_evidence
    from imunoise.online import OnlineConfig

    t0 = time.perf_counter()
    _, spec = dense.parse_outages(a.outages)
    scen = {"duration_s": a.duration, "n_stops": a.stops, "motion_noise": "none", "gnss_sigma_m": a.rtk_sigma,
            **imu_noise_kwargs(rec, seeds[0])}
    res = dense.run_sim(seeds, spec=spec, regimes=[parse_gnss(g) for g in a.gnss_regime],
                        noise_seeds=list(range(1, 1 + a.noise_seeds)), methods=tuple(a.methods.split(",")),
                        pairs=dense.parse_pairs(a.pairs), workers=a.workers, base=OnlineConfig(latency=a.latency),
                        n_boot=a.bootstrap, boot_seed=0, **scen)
    res["elapsed_s"] = time.perf_counter() - t0
    res["latency_s"] = a.latency
    res["seed_role"] = a.seed_role
    write_evidence(res, out, title=f"imunoise: dense-window evidence, real-noise replay {Path(rec).name}, "
                   f"{len(seeds)} simulated drives")


def _denial(rec: str, seeds: list[int], a: argparse.Namespace, out: Path, sigma: tuple[float, float, float]) -> None:
    from imunoise.experiments import denial
    from imunoise.experiments.common import imu_noise_kwargs
    from imunoise.experiments.report import write_sim

    t0 = time.perf_counter()
    static_s = 3600.0 * a.static_hours
    kw = {"duration_s": a.duration, "n_stops": a.stops, "n_outages": 4, "motion_noise": "none",
          "gnss_sigma_m": sigma, **imu_noise_kwargs(rec, seeds[0], reserve_s=static_s)}
    res = denial.run_sim(seeds, methods=denial.METHODS, workers=a.workers, static_recording_s=static_s, **kw)
    res["elapsed_s"] = time.perf_counter() - t0
    res["seed_role"] = a.seed_role
    write_sim(res, out, title=f"imunoise: denial experiment, real-noise replay {Path(rec).name} "
              f"({len(seeds)} seeds)")


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("recordings", nargs="+", help="one static recording (.npz) per IMU unit")
    p.add_argument("--out", required=True, help="output folder (one sub-folder per unit and run)")
    p.add_argument("--seeds", type=int, default=6, help="drives per unit (default 6)")
    p.add_argument("--seed0", type=int, default=4_000_000, help="first seed of the first unit (default 4000000)")
    p.add_argument("--which", default="online,denial", help="online, denial or both (default)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--seed-role", choices=("dev", "report"), default="dev")
    p.add_argument("--duration", type=float, default=600.0, help="drive length [s] (default 600)")
    p.add_argument("--stops", type=int, default=4, help="stops per drive (default 4)")
    p.add_argument("--static-hours", type=float, default=1.0, help="denial: static part [h] (default 1)")
    p.add_argument("--outages", default="dense:60:20")
    p.add_argument("--gnss-regime", action="append", default=None,
                   help="online regimes (default rtk and noise:1.5,3)")
    p.add_argument("--noise-seeds", type=int, default=2, help="GNSS noise seeds of the noise regime (default 2)")
    p.add_argument("--methods", default="plain,static_var,av,em,gmwm")
    p.add_argument("--pairs", default="gmwm/av,gmwm/em,em/av")
    p.add_argument("--latency", type=float, default=1.0, help="online: model latency [s] (default 1)")
    p.add_argument("--rtk-sigma", type=sigma_triple, default=(0.02, 0.02, 0.05), help="RTK fixes' σ N,E,D [m]")
    p.add_argument("--meter-sigma", type=sigma_triple, default=(1.5, 1.5, 3.0), help="denial: meter-level σ N,E,D [m]")
    p.add_argument("--bootstrap", type=int, default=2000)
    a = p.parse_args(argv)
    a.gnss_regime = a.gnss_regime or ["rtk", "noise:1.5,3"]
    which = {w.strip() for w in a.which.split(",")}
    root = Path(a.out)
    root.mkdir(parents=True, exist_ok=True)
    log = []
    for k, rec in enumerate(a.recordings):
        seeds = list(range(a.seed0 + STEP * k, a.seed0 + STEP * k + a.seeds))
        name = Path(rec).stem.split("_")[-1]
        runs = []
        if "online" in which:
            runs.append((f"{name}_online", lambda o, r=rec, s=seeds: _online(r, s, a, o)))
        if "denial" in which:
            runs.append((f"{name}_denial_rtk", lambda o, r=rec, s=seeds: _denial(r, s, a, o, a.rtk_sigma)))
            runs.append((f"{name}_denial_meter", lambda o, r=rec, s=seeds: _denial(r, s, a, o, a.meter_sigma)))
        for label, fn in runs:
            t0 = time.perf_counter()
            fn(root / label)
            log.append({"run": label, "recording": Path(rec).name, "seeds": [seeds[0], seeds[-1]],
                        "wall_s": round(time.perf_counter() - t0, 1)})
            print(json.dumps(log[-1]), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
