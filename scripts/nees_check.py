"""Filter consistency on the simulator: NEES of the GNSS-aided online run per method (issue 13, acceptance 3).

At every 1 Hz reference epoch after the first ``--skip`` seconds of a simulated drive (meter-level GNSS, the
motion law of the experiments' default), the normalised estimation error squared of the position (3 dof:
e = estimate − truth in NED metres, NEES = eᵀ P_rr⁻¹ e with P_rr the filter's position covariance), of the
velocity (3 dof) and of position + velocity (6 dof), and the share of epochs inside the two-sided 95 % χ² band of
their dof. A consistent filter has about 95 % of its epochs inside; the mean NEES should be near the dof. The
share's 95 % CI is a percentile bootstrap over the drives (the independent units; epochs of one drive are
correlated), seeded. ``oracle_law`` (the filter told the law per sample) is the batch filter of
:mod:`imunoise.experiments.oracle_law`; every other method is the online engine stepped sample by sample.

    python scripts/nees_check.py --seeds 0-9 --methods plain,gmwm,gmwm_dyn,oracle --out out/nees
    python scripts/nees_check.py --seeds 3100-3109 --methods gmwm,oracle,oracle_law,adaptive --out out/nees_ceiling
    python scripts/nees_check.py --seeds 0-9 --methods gmwm_dyn --duration 1800 --stops 12 --out out/nees_long
"""

from __future__ import annotations

import argparse
import json
import logging
import multiprocessing as mp
import sys
from pathlib import Path

import numpy as np
from scipy.stats import chi2


def _seeds(text: str) -> list[int]:
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(x) for x in text.split(",")]


def nees_values(e: np.ndarray, P: np.ndarray) -> tuple[float, float, float]:
    """NEES of position (3 dof), velocity (3 dof) and position + velocity (6 dof) of the error ``e`` (NED m,
    m/s) under the filter's covariance ``P`` (its 6×6 position-velocity block or larger)."""
    return (float(e[:3] @ np.linalg.solve(P[:3, :3], e[:3])), float(e[3:6] @ np.linalg.solve(P[3:6, 3:6], e[3:6])),
            float(e[:6] @ np.linalg.solve(P[:6, :6], e[:6])))


def _error(sc, j: int, llh: np.ndarray, euler: np.ndarray, vel: np.ndarray) -> np.ndarray:
    from imunoise.nav.solution import antenna_llh
    from imunoise.online import ned_offset

    ant = antenna_llh(llh[None], euler[None], sc.lever)
    dn, de = ned_offset(ant, sc.ref.llh[j][None])
    return np.array([dn[0], de[0], -(ant[0, 2] - sc.ref.llh[j][2]), *(vel - sc.ref.vel_ned[j])])


def law_epochs(sc, gnss, ref_i: dict, base=None):
    """(reference index, error, 9×9 covariance) at the scored epochs of the ``oracle_law`` filter: the batch
    filter told the law per sample (:mod:`imunoise.experiments.oracle_law`, the run of its full-GNSS pass) with
    the navigation covariance kept at every sample; it has no online engine to step, so it is run here whole."""
    from imunoise.experiments.oracle_law import _fixes, _run, law_filter
    from imunoise.nav.state import N_NAV
    from imunoise.nav.step_filter import new_outputs

    lf = law_filter(sc, (), base)
    ekf, t = lf.ekf, lf.imu.t
    n = t.size
    out = new_outputs(n, store_cov=True, has_sf=bool(np.all(ekf.layout.scale_index >= 0)))
    out.pos[0], out.vel[0], out.att[0] = sc.init.llh, sc.init.vel_ned, sc.init.euler
    out.cov[0] = ekf.P[:N_NAV, :N_NAV]
    _run(lf, ekf.arrays(), _fixes(gnss, ekf), out, 0, n - 1)
    for k in range(n):
        j = ref_i.get(round(float(t[k]), 6))
        if j is not None:
            yield j, _error(sc, j, out.pos[k], out.att[k], out.vel[k]), out.cov[k]


def nees_run(args: tuple) -> dict:
    seed, method, gnss_spec, motion, skip, duration, stops = args
    from imunoise.experiments.common import simulate_scenario
    from imunoise.experiments.dense import WARM_METHODS, earlier_prior, method_setup
    from imunoise.experiments.gnss_regimes import parse_gnss
    from imunoise.online import OnlineNavigator

    logging.getLogger("imunoise").setLevel(logging.WARNING)
    scen_kw = {"motion_noise": motion, "duration_s": duration, "n_stops": stops}
    sc = simulate_scenario(seed, n_outages=0, **scen_kw)
    regime = parse_gnss(gnss_spec)
    gnss = regime.apply(sc.gnss, 1_000_003 * seed + 1)
    rt = np.asarray(sc.ref.t)
    pick = np.abs(rt - np.round(rt)) < 1e-6  # 1 Hz epochs of the reference
    pick &= rt >= sc.init.t + skip
    ref_i = {round(float(x), 6): j for j, x in zip(np.flatnonzero(pick), rt[pick])}
    n3, nv, n6 = [], [], []
    if method == "oracle_law":
        for _, e, P in law_epochs(sc, gnss, ref_i):
            for acc, x in zip((n3, nv, n6), nees_values(e, P)):
                acc.append(x)
        return {"seed": seed, "method": method, "nees3": n3, "neesv": nv, "nees6": n6}
    prior = (earlier_prior(seed, regime, 1, n_drives=WARM_METHODS[method], **scen_kw)
             if method in WARM_METHODS else None)
    cfg, models, upd = method_setup(method, sc, prior=prior)
    nav = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate, initial_models=models)
    t = np.asarray(sc.imu.t)
    dth, dv = sc.imu.increments()
    gt, gl, gs = np.asarray(gnss.t), np.asarray(gnss.llh), np.asarray(gnss.sigma_ned)
    k = 0
    for i in range(t.size):
        while k < gt.size and gt[k] <= t[i]:
            nav.push_gnss(gt[k], gl[k], gs[k])
            k += 1
        nav.push_imu(t[i], dth[i], dv[i])
        if upd is not None:
            upd.step(nav)
        j = ref_i.get(round(float(t[i]), 6))
        if j is None:
            continue
        st = nav.ekf.state()
        e = _error(sc, j, st["llh"], st["euler"], st["vel_ned"])
        for acc, x in zip((n3, nv, n6), nees_values(e, nav.ekf.P)):
            acc.append(x)
    return {"seed": seed, "method": method, "nees3": n3, "neesv": nv, "nees6": n6}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seeds", default="0-9", help="simulator seeds, a-b or a,b,c (default 0-9)")
    p.add_argument("--methods", default="plain,gmwm,gmwm_dyn,oracle")
    p.add_argument("--gnss", default="noise:1.5,3,1")
    p.add_argument("--motion-noise", default="drive0708")
    p.add_argument("--duration", type=float, default=600.0, help="drive length in s (default 600, the simulator's)")
    p.add_argument("--stops", type=int, default=4, help="stops in a drive (default 4, the simulator's)")
    p.add_argument("--skip", type=float, default=60.0, help="seconds after the start not scored (alignment)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--out", required=True)
    a = p.parse_args()
    seeds = _seeds(a.seeds)
    methods = [m.strip() for m in a.methods.split(",") if m.strip()]
    jobs = [(s, m, a.gnss, a.motion_noise, a.skip, a.duration, a.stops) for s in seeds for m in methods]
    with mp.get_context("fork").Pool(a.workers) as pool:
        runs = pool.map(nees_run, jobs)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = {}
    lines = [f"NEES on {len(seeds)} simulated drives of {a.duration:g} s with {a.stops} stops (seeds {a.seeds}, "
             f"GNSS {a.gnss}, motion law {a.motion_noise}), "
             f"1 Hz epochs after {a.skip:g} s; [95 % CI] of the share inside: bootstrap over the drives", "",
             "| method | epochs | pos NEES mean (3 dof) | inside 95 % band | vel NEES mean (3 dof) | inside | "
             "pos+vel NEES mean (6 dof) | inside |",
             "|---|---:|---:|---:|---:|---:|---:|---:|"]
    bands = {"3": chi2.ppf([0.025, 0.975], 3), "v": chi2.ppf([0.025, 0.975], 3), "6": chi2.ppf([0.025, 0.975], 6)}
    rng = np.random.default_rng(0)
    for m in methods:
        mine = [r for r in runs if r["method"] == m]
        draws = rng.integers(0, len(mine), size=(2000, len(mine)))  # the same drives for the three
        rows[m] = {}
        cells = []
        for dof in ("3", "v", "6"):  # position, velocity, both
            per = [np.asarray(r[f"nees{dof}"]) for r in mine]
            lo, hi = bands[dof]
            inside = np.array([np.sum((x >= lo) & (x <= hi)) for x in per], dtype=float)
            count = np.array([x.size for x in per], dtype=float)
            share = float(inside.sum() / count.sum())
            boot = inside[draws].sum(axis=1) / count[draws].sum(axis=1)
            ci = [float(v) for v in np.percentile(boot, [2.5, 97.5])]
            allv = np.concatenate(per)
            rows[m].update({f"nees{dof}_mean": float(allv.mean()), f"inside{dof}": share, f"inside{dof}_ci": ci,
                            f"per_drive_inside{dof}": (inside / count).tolist()})
            cells.append(f"{allv.mean():.2f} | {share:.1%} [{ci[0]:.1%}, {ci[1]:.1%}]")
        rows[m]["epochs"] = int(sum(len(r["nees3"]) for r in mine))
        lines.append(f"| {m} | {rows[m]['epochs']} | " + " | ".join(cells) + " |")
    text = "\n".join(lines)
    (out / "nees.json").write_text(json.dumps({"seeds": seeds, "gnss": a.gnss, "motion": a.motion_noise,
                                               "duration_s": a.duration, "stops": a.stops,
                                               "methods": rows}, indent=1))
    (out / "nees.md").write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
