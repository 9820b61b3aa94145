"""The law-aware oracle against the constant-model oracle and the plain filter (issue 21 §2, acceptance 1).

Per law (a shipped name or law file; default the default law and the four law files of issue 21), 10 simulated
10-minute drives (development seeds, default 2000–2009), dense windows of 60 s every 20 s, meter-level GNSS
(``noise:1.5,3,1``, noise seed 1): mean end-of-window drift of ``oracle_law``, ``oracle`` and ``plain``, all
three through the same batch filter path (:func:`imunoise.experiments.oracle_law.run_windows_law`, only the
models differ), and the paired ratios with drives as clusters (:func:`imunoise.experiments.stats.paired_entry`).

    python benchmarks/bench_oracle_law.py [--seed0 2000] [--seeds 10] [LAW ...]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from imunoise.experiments import dense
from imunoise.experiments.common import simulate_scenario
from imunoise.experiments.gnss_regimes import parse_gnss
from imunoise.experiments.online_exp import method_config
from imunoise.experiments.oracle_law import run_windows_law
from imunoise.experiments.stats import paired_entry
from imunoise.nav.defaults import default_axis_models

LAWS = ("drive0708", "gyro_departure_step", "gyro_moving_gm", "accel_moving_gm", "warmup")


def check_law(law: str, seeds: range) -> dict:
    """Mean drift per method and the paired ratios oracle_law/oracle, oracle_law/plain, oracle/plain."""
    regime = parse_gnss("noise:1.5,3,1")
    vals: dict[str, list] = {"oracle_law": [], "oracle": [], "plain": []}
    t0 = time.perf_counter()
    for seed in seeds:
        sc = simulate_scenario(seed, n_outages=0, motion_noise=law)
        windows = dense.dense_windows(sc, dense.parse_outages("dense:60:20")[1])
        gnss = regime.apply(sc.gnss, 1_000_003 * seed + 1)
        cfg, oracle_models = method_config("oracle", sc)
        plain = default_axis_models(sc.rate, cfg.ekf.fallback)
        for name, models in (("oracle_law", None), ("oracle", oracle_models), ("plain", plain)):
            vals[name].append([w["drift"] for w in run_windows_law(sc, gnss, windows, models=models)["windows"]])
    means = {k: float(np.mean([np.mean([x for x in d if x is not None]) for d in v])) for k, v in vals.items()}
    paired = [paired_entry(a, b, "drift", vals) for a, b in
              (("oracle_law", "oracle"), ("oracle_law", "plain"), ("oracle", "plain"))]
    return {"law": law, "mean_drift_m": means, "wall_s": round(time.perf_counter() - t0, 1),
            "paired": [{k: e[k] for k in ("method", "baseline", "ratio", "ci", "n_drives", "df")} for e in paired]}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("laws", nargs="*", default=list(LAWS))
    p.add_argument("--seed0", type=int, default=2000)
    p.add_argument("--seeds", type=int, default=10)
    a = p.parse_args()
    for law in a.laws:
        print(json.dumps(check_law(law, range(a.seed0, a.seed0 + a.seeds))), flush=True)


if __name__ == "__main__":
    main()
