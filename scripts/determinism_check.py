"""How much the learner test's drive moves under rounding differences, as another machine would make them.

Runs the drive of tests/online/test_motion_learner.py (simulated, 420 s, meter-level GNSS, the drift learner
with a fixed latency) and prints its last position and the learner's decisions as JSON. With ``--ulp-seed S``
every IMU increment is first moved by at most one ulp (up, down or not, seeded): the rounding noise of another
CPU, BLAS kernel or library version, made here on purpose. Run it under other numba targets or BLAS kernels
(environment variables, see docs/evidence/cross_machine_determinism.md) to measure those directly.

    python scripts/determinism_check.py                 # the reference
    python scripts/determinism_check.py --ulp-seed 2    # one perturbed copy
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from imunoise.experiments.common import simulate_scenario
from imunoise.experiments.dense import method_setup
from imunoise.experiments.gnss_regimes import parse_gnss
from imunoise.online import OnlineNavigator
from imunoise.online.motion_noise import MotionNoiseConfig


def perturb_ulp(a: np.ndarray, seed: int) -> np.ndarray:
    """``a`` with each entry moved to its next float up or down, or kept (one third each, seeded)."""
    step = np.random.default_rng(seed).integers(-1, 2, a.shape)
    return np.where(step > 0, np.nextafter(a, np.inf), np.where(step < 0, np.nextafter(a, -np.inf), a))


def run(ulp_seed: int | None) -> dict:
    """Last position [rad, rad, m], the identified structures and the learner's decisions of one run."""
    sc = simulate_scenario(7, n_outages=0, duration_s=420.0, n_stops=2)
    gnss = parse_gnss("noise:1.5,3").apply(sc.gnss, 11)
    cfg, models, _ = method_setup("gmwm_dyn", sc)
    mc = MotionNoiseConfig(outage_s=15.0, every_s=15.0, warm_rounds=1, choose_rounds=3, confirm_rounds=3,
                           alpha=0.9, margin=0.0, nis_alpha=1e-9)
    cfg = cfg.with_(worker="inline", latency=1.0, motion_noise=mc)
    if ulp_seed is not None:
        sc.imu.dtheta[...] = perturb_ulp(sc.imu.dtheta, ulp_seed)
        sc.imu.dv[...] = perturb_ulp(sc.imu.dv, ulp_seed + 1)
    res = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate, initial_models=models).run(sc.imu, gnss)
    structures = [{a: v["structure"] for a, v in e["axes"].items()} for e in res.events
                  if e["event"] in ("identified", "refit")]
    decisions = [(e["event"], e.get("t_round")) for e in res.events if e["event"].startswith("motion_noise")]
    return {"ulp_seed": ulp_seed, "llh_end": [float(x) for x in res.llh[-1]], "structures": structures,
            "decisions": decisions}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ulp-seed", type=int, default=None, help="move every IMU increment by ≤ 1 ulp (seeded)")
    print(json.dumps(run(ap.parse_args().ulp_seed)))


if __name__ == "__main__":
    main()
