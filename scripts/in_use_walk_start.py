"""One vehicle of a carry-over run, diagnosed: where ``in_use``'s drift arises when its learned wander is a random walk
(docs/evidence/in_use_ceiling.md, 'One vehicle').

    python scripts/in_use_walk_start.py --results out/carry/gyro_moving_gm/results.json --seed 7100010

The vehicle's scored drive and its earlier drive are simulated again (600 s, 4 stops, the run's law, GNSS
``noise:1.5,3,1`` with the run's first noise seed); ``in_use``'s static part is learned again (the ``gmwm`` row's
fits on the earlier drive); the in-motion part is the one the run learned (its ``in_use_models`` entry: white factor
and walk k per axis). Two filters of that part: the walk as the model file's filter carries it (a Gauss–Markov of
τ = 10⁶ s, σ = k√(τ/2), so P0 = σ² = k²·5·10⁵ s) and a Gauss–Markov of the same driving density with τ = the drive's
moving time T_M (P0 = k² T_M / 2). Printed: per window the run's drifts (gmwm, in_use, oracle_law) and the two
filters', the aided run's horizontal RMS, and at each window start the aided run's yaw error, its 1σ and its gyro-z
error estimate.
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np

REGIME = "noise:1.5,3,1"


def main(argv=None) -> int:
    from imunoise.experiments import dense
    from imunoise.experiments.carry_over import earlier_scenarios, learning_drives
    from imunoise.experiments.common import filter_models, simulate_scenario
    from imunoise.experiments.dense_warm import gmwm_on_drives
    from imunoise.experiments.gnss_regimes import parse_gnss
    from imunoise.experiments.in_use_method import in_motion_law_filter
    from imunoise.experiments.oracle_law import run_windows_law
    from imunoise.nav.metrics import nav_errors
    from imunoise.online import OnlineConfig

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--results", required=True, help="results.json of an `experiment online --vehicle-drives 2` run")
    p.add_argument("--seed", type=int, required=True)
    args = p.parse_args(argv)
    rep = json.loads(open(args.results).read())
    k_rep = rep["seeds"].index(args.seed)
    run_drift = {m: rep["per_window"][REGIME]["drift"][m][k_rep][0] for m in ("gmwm", "in_use", "oracle_law")}
    axes = rep["in_use_models"][f"{args.seed}/{REGIME}/1"]["in_motion"]["axes"]
    kw = {"duration_s": 600.0, "n_stops": 4, "streams": [], "motion_noise": rep["scenario"]["motion_noise"]}
    base = OnlineConfig(latency=0.5)
    sc = simulate_scenario(args.seed, n_outages=0, **kw)
    windows = dense.dense_windows(sc, dense.parse_outages("dense:60:20")[1])
    rg = parse_gnss(REGIME)
    gnss = rg.apply(sc.gnss, 1_000_003 * args.seed + 1)
    d = learning_drives(args.seed, 2, earlier_scenarios(args.seed, 1, **kw), rg, 1)
    pairs = filter_models(list(gmwm_on_drives(d, base).fits), sc.rate, base.with_(ekf=d[0][0].ekf_config()))
    wf = [axes[a]["white_factor"]["value"] or 1.0 for a in axes]
    k = [axes[a]["bias"].get("k") or 0.0 for a in axes]
    t_m = float(np.count_nonzero(~np.asarray(sc.static_truth, dtype=bool))) / sc.rate
    variants = {"walk_tau_1e6": ([x * math.sqrt(1e6 / 2) for x in k], [1e6] * 6),
                "gm_tau_T_M": ([x * math.sqrt(t_m / 2) for x in k], [t_m] * 6)}
    print(f"learned part: white factor {wf}, walk k {k} [unit/√s]; moving time T_M {t_m:.1f} s", flush=True)
    res = {}
    for name, (sig, tau) in variants.items():
        r = run_windows_law(sc, gnss, windows, base=base, keep=True,
                            make=lambda s, st, b, sig=sig, tau=tau: in_motion_law_filter(s, pairs, wf, sig, tau, st, b))
        full = r.pop("_full")
        err = nav_errors(full.t, full.antenna_llh(sc.lever), full.vel_ned, full.euler, sc.ref)
        r["at_start"] = []
        for s, _ in windows:
            i, j = int(np.searchsorted(err.t, s)), int(np.searchsorted(full.t, s))
            r["at_start"].append((float(np.degrees(err.att[i, 2])), float(np.degrees(full.std[j, 8])),
                                  float(np.degrees(full.gyro_error[j, 2]) * 3600.0)))
        res[name] = r
        print(f"{name}: aided horizontal RMS {r['horizontal_rms_m']:.2f} m", flush=True)
    print("window | t − t0 [s] | run: gmwm, in_use, oracle_law [m] | walk_tau_1e6, gm_tau_T_M [m] | walk_tau_1e6 at "
          "the start: yaw error, yaw 1σ [deg], gyro-z error estimate [deg/h]")
    for j, (s, _) in enumerate(windows):
        print(j, f"{s - sc.init.t:.0f}", *(f"{run_drift[m][j]:.0f}" for m in run_drift), "|",
              *(f"{res[v]['windows'][j]['drift']:.0f}" for v in variants), "|",
              *(f"{x:.2f}" for x in res["walk_tau_1e6"]["at_start"][j]))
    for v in variants:
        print(f"{v}: mean drift {np.mean([w['drift'] for w in res[v]['windows']]):.1f} m")
    print("run: mean drift " + ", ".join(f"{m} {np.mean(x):.1f} m" for m, x in run_drift.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
