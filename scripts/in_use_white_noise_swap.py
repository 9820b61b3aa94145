"""The gyro white factor of the in-use estimate on one replayed learning drive with its gyro noise swapped
(docs/evidence/in_use_carry_over.md, 'Why some ADIS16405 gyro white factors exceed 1'): same trajectory, same
GNSS fixes and noise, same accelerometer errors, same static part; only the gyro errors differ:

* ``real``: the recording's stretch as the replay puts it (:mod:`imunoise.sim.replay`);
* ``white_static``: Gaussian white noise whose density per axis is the static part's own N (the truth of the
  white factor is then exactly 1 against the static part, and the gyro noise has no other term);
* ``white_log``: Gaussian white noise at the whole log's white level N = σ_A(1 s)·√(1 s) per axis;
* ``white_static_real_slow``: ``white_static`` with its slow band (the 60 s moving average) replaced by the
  recording's: the real errors at periods ≳ 60 s, white noise above;
* ``real_white_slow``: the recording with its slow band replaced by that of ``white_static``: the real errors
  above, white noise at periods ≳ 60 s.

The static part is the online engine's schedule on the learning drive's planned stops
(:func:`in_use_white_diagnosis.static_part`, six axes), so it is the same for the three variants. The factor is the
in-motion estimate's no-wander gyro white factor (every gyro estimate of the report run with a white interval that
excludes 1 is a no-wander one): the log factor by a bounded golden search on the innovation NLL
(:class:`imunoise.inuse.likelihood.DriveLikelihood`, accelerometers at factor 1), its 95 % Wald interval from the
NLL's curvature in log f (central difference, step 0.25), as :func:`imunoise.inuse.estimate_in_motion` does.

Usage: python scripts/in_use_white_noise_swap.py REC.npz --seed0 7500000 --seeds 2 [--unit-seed 1] [--out J.json]
(development seeds: vehicle s = seed0 + v learns on the simulated drive s + 7 000 000, stretch 2v of REC).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from in_use_white_diagnosis import N_DRIVE, F, plan_stops, white_level  # noqa: E402

SLOW_S = 60.0  # the moving average [s] that splits slow from fast errors
H = 0.25  # step of the curvature in log f (estimate_in_motion's default)
LOG_F_RANGE = (math.log(0.2), math.log(50.0))


def static_models(errors: np.ndarray, intervals: list[tuple[float, float]]) -> list:
    """Six filter models of the engine's schedule on the stops (gyro and accelerometer errors of the stretch)."""
    from in_use_white_diagnosis import static_part

    g = static_part(errors[:, :3], intervals)
    a = static_part(errors[:, 3:], intervals, first_axis=3)
    return [*g, *a]


def white_factor(sc, gnss, models) -> dict:
    """No-wander gyro white factor with its Wald interval (module docstring)."""
    from scipy.optimize import minimize_scalar

    from imunoise.inuse.estimate import static_models
    from imunoise.inuse.likelihood import DriveLikelihood, Theta

    lik = DriveLikelihood([replace(sc, gnss=gnss)], static_models(models, sc.rate))

    def nll(u: float) -> float:
        f = math.exp(u)
        return lik.nll(Theta(white=(f, f, f, 1.0, 1.0, 1.0)))

    r = minimize_scalar(nll, bounds=LOG_F_RANGE, method="bounded", options={"xatol": 0.03, "maxiter": 14})
    u = float(r.x)
    curv = (nll(u + H) - 2 * nll(u) + nll(u - H)) / (H * H)
    sd = 1.0 / math.sqrt(curv) if curv > 0 else math.inf
    return {"factor": math.exp(u), "ci95": [math.exp(u - 1.96 * sd), math.exp(u + 1.96 * sd)],
            "nll": nll(u), "nll_at_1": nll(0.0), "runs": lik.runs}


def main(argv: list[str]) -> int:
    from scipy.ndimage import uniform_filter1d

    from imunoise.experiments.carry_over import earlier_scenarios, learning_drives
    from imunoise.experiments.common import imu_noise_kwargs
    from imunoise.experiments.gnss_regimes import parse_gnss
    from imunoise.imu import ImuData
    from imunoise.noise.equivalent_noise import equivalent_noise
    from imunoise.sim.replay import load_recording

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("recording")
    p.add_argument("--seed0", type=int, required=True, help="first vehicle seed (development seeds)")
    p.add_argument("--seeds", type=int, default=1)
    p.add_argument("--noise-seed", type=int, default=1, help="seed of the synthetic white noise")
    p.add_argument("--variants", default="real,white_static,white_log,white_static_real_slow,real_white_slow",
                   help="comma-separated variants to run (module docstring)")
    p.add_argument("--out", default=None)
    a = p.parse_args(argv)
    rec = load_recording(str(Path(a.recording).resolve()))
    everywhere = np.ones(rec.n, dtype=bool)
    n_log = [white_level(np.asarray(rec.errors[:, j]), everywhere) for j in range(3)]
    kw = {"duration_s": 600.0, "n_stops": 4, "motion_noise": "none", "gnss_sigma_m": (0.02, 0.02, 0.05),
          **imu_noise_kwargs(a.recording, a.seed0, vehicle_drives=2)}
    rg = parse_gnss("noise:1.5,3,1")
    rows = []
    for v in range(a.seeds):
        seed = a.seed0 + v
        c0 = time.process_time()
        earlier = earlier_scenarios(seed, 1, **kw)
        sc, gnss = learning_drives(seed, 2, earlier, rg, 1)[0]
        err = np.asarray(rec.errors[2 * v * N_DRIVE:(2 * v + 1) * N_DRIVE])
        models = static_models(err, plan_stops(seed + 7_000_000)[:-1])
        n_static = [equivalent_noise(models[j], F, horizon_s=300.0).N for j in range(3)]
        rng = np.random.default_rng(np.random.SeedSequence([a.noise_seed, seed]))
        z = rng.standard_normal((N_DRIVE, 3))
        dt = 1.0 / F
        row = {"seed": seed, "learning_drive": sc.name, "N_static": n_static, "N_log": n_log, "variants": {}}
        w_static = z * (np.asarray(n_static) * math.sqrt(F))[None, :]

        def slow(x: np.ndarray) -> np.ndarray:
            # mirrored ends: repeating the end sample ("nearest") gives the first and last 30 s that sample's
            # value over half the window, an offset of order the per-sample noise (measured: 1e-3 rad/s)
            return uniform_filter1d(x, size=int(SLOW_S * F), axis=0, mode="mirror")

        real = err[:, :3]
        variants = {"real": None, "white_static": w_static,
                    "white_log": z * (np.asarray(n_log) * math.sqrt(F))[None, :],
                    "white_static_real_slow": w_static - slow(w_static) + slow(real),
                    "real_white_slow": real - slow(real) + slow(w_static)}
        for name, new in ((k, x) for k, x in variants.items() if k in a.variants.split(",")):
            if new is None:
                s2 = sc
            else:  # the drive's sample k carries stretch sample k; swap the gyro error alone
                dth = np.asarray(sc.imu.dtheta) + (new - real)[-sc.imu.t.size:] * dt
                s2 = replace(sc, imu=ImuData(t=sc.imu.t, dtheta=dth, dv=sc.imu.dv))
            row["variants"][name] = white_factor(s2, gnss, models)
            print(json.dumps({"seed": seed, name: row["variants"][name]}), flush=True)
        row["cpu_s"] = time.process_time() - c0
        rows.append(row)
    if a.out:
        Path(a.out).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
