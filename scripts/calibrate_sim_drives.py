"""`imunoise calibrate` on simulated drives whose IMU truth is in the family (WN + RW): refusals, N and K
against the truth, and the stops' motion, in four arms of 12 drives each.

Arms (``--arms``):

* ``speed-default``: the drive's reference speed given (as ``--ref`` does), default motion law (``drive0708``);
* ``speed-none``: the reference speed given, law ``none`` (moving errors = the static model);
* ``nospeed-default``: no speed source, default law;
* ``nospeed-none``: no speed source, law ``none`` (cruising that no IMU can tell from a stop): the expected
  outcome is the one-line diagnosis of a log with implausibly many stops (a :class:`DataError` naming
  ``--gnss``/``--ref``), not a fit-check refusal.

Drives: ``--duration`` s (default 1800) with ``--stops`` traffic-light stops of 10–90 s (default 12) after a
60 s initial stop, IMU truth ``WN+RW`` with the ``mems`` preset values at 100 Hz, seed s for drive s.

Per axis: refused (``AxisCalibration.refused``, the export gate of the day: rerun after the gate changes), N/N_true
(pass: within ±5 %), K (a value: K/K_true in 0.5–2; a bound: bound/K_true ≥ 1). Per drive: stops, seconds kept,
and the seconds of kept stop samples at which the true speed exceeds 0 (``motion_s``: motion pooled as a
stop). Acceptance: 0 refused axes and every N and K inside its rule in the first three arms; the diagnosis on
every drive of the fourth.

    PYTHONPATH=src python scripts/calibrate_sim_drives.py --seeds 6200000-6200011 [--arms speed-default ...]
        [--json out.json]

Development seeds were 3600–3699; the report seeds 6 200 000–6 200 999 (docs/evidence/calibrate_stops.md).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

ARMS = ("speed-default", "speed-none", "nospeed-default", "nospeed-none")
N_TOL = 0.05
K_RANGE = (0.5, 2.0)
MOVING_SPEED = 0.0  # m/s: a kept sample faster than this is motion (the reference is exactly 0 at a stop)


def seed_list(spec: list[str]) -> list[int]:
    out: list[int] = []
    for s in spec:
        if "-" in s:
            a, b = (int(x) for x in s.split("-"))
            out += list(range(a, b + 1))
        else:
            out.append(int(s))
    return out


def simulate(seed: int, law: str, duration: float, n_stops: int):
    from imunoise.sim import DriveConfig, simulate_drive

    cfg = DriveConfig(duration_s=duration, n_stops=n_stops, stop_range_s=(10.0, 90.0), static_s=60.0,
                      motion_noise=law)
    return simulate_drive(cfg, "WN+RW", seed=seed)


def as_log(d, with_speed: bool, name: str = "sim"):
    from imunoise.calibrate import ImuLog

    g, a = d.imu.rates()
    speed = None
    if with_speed:
        ref = d.reference
        speed = (np.asarray(ref.t, dtype=float), np.linalg.norm(np.asarray(ref.vel_ned)[:, :2], axis=1))
    return ImuLog(name, np.asarray(d.imu.t, dtype=float), g, a, float(d.imu.rate_hz), speed)


def motion_kept(d, stops) -> float:
    """Seconds of kept stop samples at which the true (IMU-rate) speed exceeds :data:`MOVING_SPEED`."""
    v = np.linalg.norm(np.asarray(d.reference_full.vel_ned)[:, :2], axis=1)
    n = sum(int(np.count_nonzero(v[s.i0 : s.i1] > MOVING_SPEED)) for s in stops)
    return n / float(d.imu.rate_hz)


def run_drive(seed: int, arm: str, duration: float, n_stops: int) -> dict:
    from imunoise.calibrate import calibrate
    from imunoise.errors import DataError
    from imunoise.sim.motion import DEFAULT_MOTION

    with_speed, law = arm.startswith("speed"), arm.split("-")[1]
    law = DEFAULT_MOTION if law == "default" else law
    d = simulate(seed, law, duration, n_stops)
    truth = {ax: m.continuous(float(d.imu.rate_hz)) for ax, m in d.imu_models.items()}
    row: dict = {"seed": seed, "arm": arm, "true_stops": n_stops + 2}
    t0 = time.perf_counter()
    try:
        res = calibrate([as_log(d, with_speed, f"sim{seed}")], seed=0)
    except DataError as exc:
        row.update(outcome="error", message=str(exc), seconds=time.perf_counter() - t0)
        return row
    ls = res.logs[0]
    row.update(outcome="fit", n_stops=len(ls.stops), static_s=ls.static_s, motion_s=motion_kept(d, ls.stops),
               seconds=time.perf_counter() - t0, axes={})
    for ax, a in res.axes.items():
        rn = a.N / truth[ax]["WN.noise_density"]
        rk = a.K_reported / truth[ax]["RW.random_walk"]
        k_ok = (K_RANGE[0] <= rk <= K_RANGE[1]) if a.K_status == "value" else rk >= 1.0
        row["axes"][ax] = {"refused": a.refused, "N_ratio": rn, "K_status": a.K_status, "K_ratio": rk,
                           "N_ok": abs(rn - 1.0) <= N_TOL, "K_ok": bool(k_ok), "model": a.model}
    return row


def summarise(rows: list[dict]) -> list[str]:
    out = []
    for arm in ARMS:
        rs = [r for r in rows if r["arm"] == arm]
        if not rs:
            continue
        fits = [r for r in rs if r["outcome"] == "fit"]
        errs = [r for r in rs if r["outcome"] == "error"]
        axes = [a for r in fits for a in r["axes"].values()]
        refused = sum(a["refused"] for a in axes)
        n_bad = sum(not a["N_ok"] for a in axes)
        k_bad = sum(not a["K_ok"] for a in axes)
        line = f"{arm:<16} drives {len(rs):>3}  diagnosed {len(errs):>3}"
        if axes:
            nr = np.array([a["N_ratio"] for a in axes])
            kv = [a["K_ratio"] for a in axes if a["K_status"] == "value"]
            kb = [a["K_ratio"] for a in axes if a["K_status"] != "value"]
            line += (f"  refused {refused}/{len(axes)}  N outside ±5 %: {n_bad}  K outside rule: {k_bad}"
                     f"  N/N_true {nr.min():.3f}–{nr.max():.3f}")
            if kv:
                line += f"  K value/K_true {min(kv):.2f}–{max(kv):.2f} ({len(kv)})"
            if kb:
                line += f"  K bound/K_true {min(kb):.2f}–{max(kb):.2f} ({len(kb)})"
            line += (f"  stops {min(r['n_stops'] for r in fits)}–{max(r['n_stops'] for r in fits)}"
                     f"  motion kept {max(r['motion_s'] for r in fits):.2f} s max")
        out.append(line)
    return out


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", nargs="+", default=["3600-3611"], help="seeds or ranges a-b (development: 3600-3699)")
    p.add_argument("--arms", nargs="+", choices=ARMS, default=list(ARMS))
    p.add_argument("--duration", type=float, default=1800.0)
    p.add_argument("--stops", type=int, default=12)
    p.add_argument("--json", help="write every row here (rewritten after each drive)")
    a = p.parse_args(argv)
    rows: list[dict] = []
    for arm in a.arms:
        for seed in seed_list(a.seeds):
            r = run_drive(seed, arm, a.duration, a.stops)
            rows.append(r)
            if r["outcome"] == "error":
                print(f"{arm} {seed}: error: {r['message']}", flush=True)
            else:
                bad = [f"{ax}{' REFUSED' if v['refused'] else ''} N {v['N_ratio']:.3f} K {v['K_status']} "
                       f"{v['K_ratio']:.2f}" for ax, v in r["axes"].items()
                       if v["refused"] or not (v["N_ok"] and v["K_ok"])]
                print(f"{arm} {seed}: {r['n_stops']} stops, {r['static_s']:.0f} s, motion kept {r['motion_s']:.2f} s; "
                      f"{'; '.join(bad) or 'all axes ok'} ({r['seconds']:.0f} s)", flush=True)
            if a.json:
                with open(a.json, "w") as fh:
                    json.dump({"args": vars(a), "rows": rows}, fh, indent=1)
    print()
    print("\n".join(summarise(rows)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
