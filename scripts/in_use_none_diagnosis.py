"""Under motion law ``none``, where ``in_use`` loses against ``gmwm`` (docs/evidence/in_use_ceiling.md, 'Under
law none: the stops miss a walk').

    python scripts/in_use_none_diagnosis.py part-effect --results out/dev/none/results.json --out out/part_effect.json
    python scripts/in_use_none_diagnosis.py white-lr --law none --seeds 7400100,7400108

``part-effect`` reruns the ``in_use`` row of an ``experiment online --sim --vehicle-drives 2`` run (its seeds, 600 s
drives, 4 stops, dense:60:20, GNSS ``noise:1.5,3,1``, noise seed 1, latency 0.5 s) with the in-motion part removed:
the same static part (the ``gmwm`` row's fits on the earlier drive), no white factor, no wander. It prints the
paired end-of-window drift ratios, vehicles as clusters (percentile bootstrap, 4000 draws, seed 0): the run's
``in_use`` over the static part alone (what the in-motion estimate does) and the static part alone over the run's
``gmwm`` (what a model of one drive's stops does against one of the scored drive's). ``--variant white-rule``
reruns it with the run's own learned parts instead, each white factor whose interval contains 1 set to 1 (a rule
the estimate does not apply: a diagnosis of it); ``--variant stored`` with the parts unchanged (ratio 1 exactly:
the check that the rerun is the run); ``--variant no-wander`` with the parts' wanders removed.

``white-lr`` learns each vehicle's ``in_use`` model again and, for every sensor group whose white factor is not 1,
evaluates the innovation likelihood at the estimate and with that group's white factor set to 1 (the rest kept):
2ΔNLL against χ²₁(0.95) = 3.84 says whether the data reject factor 1, beside the Wald interval the estimate gives.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace

import numpy as np

REGIME = "noise:1.5,3,1"
SCEN = {"duration_s": 600.0, "n_stops": 4}


def paired(a: list[np.ndarray], b: list[np.ndarray], n_boot: int = 4000) -> tuple[float, float, float, list[float]]:
    """Geometric-mean ratio of per-window values a/b, windows weighted equally, vehicles as clusters: (ratio, 95 %
    CI low, high, per-vehicle ratios)."""
    per = np.array([np.mean(np.log(x / y)) for x, y in zip(a, b, strict=True)])
    w = np.array([x.size for x in a], dtype=float)
    est = float(np.exp((per * w).sum() / w.sum()))
    rng = np.random.default_rng(0)
    boot = []
    for _ in range(n_boot):
        i = rng.integers(0, per.size, per.size)
        boot.append(np.exp((per[i] * w[i]).sum() / w[i].sum()))
    lo, hi = np.percentile(boot, [2.5, 97.5])
    return est, float(lo), float(hi), [float(np.exp(p)) for p in per]


def _drifts(per_window: dict, method: str) -> list[np.ndarray]:
    return [np.asarray(x, dtype=float).ravel() for x in per_window[REGIME]["drift"][method]]


def _static_only(drives, fits, base=None, static_pieces=None):
    """``learn_in_use`` without the in-motion estimate: the static part alone."""
    from imunoise.experiments.common import filter_models
    from imunoise.experiments.in_use_method import InUseModel
    from imunoise.inuse import InMotionPart
    from imunoise.online import OnlineConfig

    scs = [replace(sc, gnss=g) for sc, g in drives]
    cfg = (base or OnlineConfig()).with_(ekf=scs[0].ekf_config())
    return InUseModel(filter_models(list(fits), scs[0].rate, cfg), InMotionPart({}), 0.0, 0,
                      [sc.name for sc in scs], static_pieces)


_STORED: dict = {}  # drive names → the run's learned in-motion part (set before the workers fork)


def _white_rule(part: dict) -> dict:
    """A stored part with every group's white factor set to 1 where its interval contains 1 or it is not identified:
    the factor kept only where the data reject 1, as the wander is kept only where its test rejects none."""
    out = json.loads(json.dumps(part))
    for ax in out["axes"].values():
        wf = ax.get("white_factor") or {}
        ci = wf.get("ci95")
        if wf.get("value") is None or ci is None or ci[0] <= 1.0 <= ci[1]:
            ax["white_factor"] = {"value": 1.0, "ci95": ci}
            ax["factor_N"] = {"value": 1.0, "ci95": ci}
    return out


def _no_wander(part: dict) -> dict:
    """A stored part without its bias wander (white factors kept)."""
    out = json.loads(json.dumps(part))
    for ax in out["axes"].values():
        ax["bias"] = {"model": "none", "ci95": {}}
        ax["factor_K"] = {"value": 1.0, "ci95": None}
    return out


def _stored(drives, fits, base=None, static_pieces=None):
    """``learn_in_use`` with the run's own learned part (``_STORED``, by the learning drives' names): the static
    part recomputed from ``fits`` as the run did, no new estimate."""
    from imunoise.inuse import InMotionPart

    m = _static_only(drives, fits, base, static_pieces)
    m.part = InMotionPart.from_dict(_STORED[tuple(m.drives)])
    return m


def part_effect(results: str, out: str, workers: int, variant: str = "static") -> dict:
    import imunoise.experiments.in_use_method as ium
    from imunoise.experiments import dense
    from imunoise.experiments.gnss_regimes import parse_gnss
    from imunoise.online import OnlineConfig

    run = json.load(open(results))
    law = run["scenario"]["motion_noise"]
    learn = ium.learn_in_use
    change = {"static": None, "stored": lambda p: p, "white-rule": _white_rule, "no-wander": _no_wander}[variant]
    if change is not None:  # the run's own parts, changed one way; "static" uses none of them
        for v in run["in_use_models"].values():
            _STORED[tuple(v["drives"])] = change(v["in_motion"])
    # the row learns in the worker through this name
    ium.learn_in_use = _static_only if variant == "static" else _stored
    try:
        res = dense.run_sim(run["seeds"], spec=dense.DenseSpec(60.0, 20.0, 60.0), regimes=(parse_gnss(REGIME),),
                            noise_seeds=(1,), methods=("in_use",), workers=workers, base=OnlineConfig(latency=0.5),
                            n_boot=200, vehicle_drives=2, motion_noise=law, **SCEN)
    finally:
        ium.learn_in_use = learn
    alt = _drifts(res["per_window"], "in_use")
    name = {"static": "static part alone", "stored": "the run's own part again", "white-rule": "white rule",
            "no-wander": "no wander"}[variant]
    rows = {f"in_use / {name}": paired(_drifts(run["per_window"], "in_use"), alt)}
    if "gmwm" in run["per_window"][REGIME]["drift"]:
        rows[f"{name} / gmwm"] = paired(alt, _drifts(run["per_window"], "gmwm"))
    summary = {"law": law, "seeds": run["seeds"], "variant": variant, "rows": rows}
    with open(out, "w") as f:
        json.dump(summary, f, indent=1)
    for name, (r, lo, hi, per) in rows.items():
        print(f"{law}: {name}: {r:.3f} [{lo:.3f}, {hi:.3f}] over {len(per)} vehicles; per vehicle "
              + " ".join(f"{x:.2f}" for x in per))
    return summary


def white_lr(law: str, seeds: list[int]) -> None:
    from imunoise.experiments.carry_over import earlier_scenarios, learning_drives
    from imunoise.experiments.common import filter_models
    from imunoise.experiments.dense_warm import gmwm_on_drives
    from imunoise.experiments.gnss_regimes import parse_gnss
    from imunoise.inuse import estimate_in_motion
    from imunoise.inuse.estimate import GROUPS, static_models
    from imunoise.inuse.likelihood import DriveLikelihood
    from imunoise.online import OnlineConfig

    base = OnlineConfig(latency=0.5)
    for seed in seeds:
        scen = {**SCEN, "motion_noise": law}
        d = learning_drives(seed, 2, earlier_scenarios(seed, 1, **scen), parse_gnss(REGIME), 1)
        scs = [replace(sc, gnss=g) for sc, g in d]
        models = filter_models(list(gmwm_on_drives(d, base).fits), scs[0].rate, base.with_(ekf=scs[0].ekf_config()))
        est = estimate_in_motion(scs, models, freq=scs[0].rate)
        lik = DriveLikelihood(scs, static_models(models, scs[0].rate))
        n_hat = lik.nll(est.theta)
        for g, idx in GROUPS.items():
            if all(abs(est.theta.white[i] - 1.0) < 1e-12 for i in idx):
                continue
            w = [1.0 if i in idx else x for i, x in enumerate(est.theta.white)]
            lr = 2.0 * (lik.nll(replace(est.theta, white=tuple(w))) - n_hat)
            wf = est.part.axis("gyro_x" if g == "gyro" else "accel_x").white_factor
            print(f"{seed} {g}: white factor {est.theta.white[idx[0]]:.3g} (given: {wf.value}, Wald 95 % "
                  f"{wf.ci95}); 2ΔNLL at factor 1 = {lr:.2f} (χ²₁ 95 %: 3.84)", flush=True)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("part-effect", help="in_use with and without its in-motion part")
    a.add_argument("--results", required=True, help="results.json of the run (rows in_use and gmwm)")
    a.add_argument("--out", required=True, help="summary JSON to write")
    a.add_argument("--workers", type=int, default=2)
    a.add_argument("--variant", choices=("static", "white-rule", "no-wander", "stored"), default="static",
                   help="static: no in-motion part; white-rule: the run's part with each white factor whose interval "
                        "contains 1 set to 1; no-wander: the run's part without its wander; stored: the run's part "
                        "as it was (must give ratio 1 exactly)")
    b = sub.add_parser("white-lr", help="the likelihood ratio of white factor 1 against the estimate")
    b.add_argument("--law", required=True)
    b.add_argument("--seeds", required=True, help="comma-separated vehicle seeds")
    args = p.parse_args(argv)
    if args.cmd == "part-effect":
        part_effect(args.results, args.out, args.workers, args.variant)
    else:
        white_lr(args.law, [int(s) for s in args.seeds.split(",")])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
