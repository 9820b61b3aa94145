"""Coverage of the record-length prediction (docs/evidence/record_length.md).

Simulates records of white noise + random walk (the family the exported pair is, realistic MEMS gyro values),
fits WN + RW by GMWM and measures

1. at the record's own length: how often the predicted 95 % interval of N and of K (= the fit's own interval,
   :func:`imunoise.noise.fitting.record_length.predict` at L₀) covers the truth;
2. from a short pilot (the first ``--pilot-fraction`` of each record, fitted on its own): the half-width it
   predicts for the full length against the spread the full-length estimates actually show over the records
   (z·SD of log K̂), as a ratio with a bootstrap 95 % CI over records, and how often the full-length estimate
   ± the pilot's predicted half-width covers the truth.

Usage:  python scripts/record_length_coverage.py --seed0 4300 --records 100 --hours 1 --out out.json
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np
from scipy.stats import norm

from imunoise.export.record_length import LengthPredictor
from imunoise.noise.estimator import gmwm
from imunoise.noise.fitting.length_covariance import LAWS
from imunoise.noise.processes import RW, WN

FREQ = 100.0
N_TRUE = 1.5e-4  # rad/s/√Hz (0.52 °/√h): a consumer MEMS gyro
K_TRUE = 2.0e-5  # rad/s²/√Hz: the random walk overtakes the white noise at T = √3·N/K = 13 s


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    p = k / n
    c = (p + z * z / (2 * n)) / (1 + z * z / n)
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return c - h, c + h


def one(seed: int, n: int, n_pilot: int, law: str) -> dict:
    model = WN(sigma2=N_TRUE**2 * FREQ) + RW(gamma2=K_TRUE**2 / FREQ)
    x = model.simulate(n, seed=seed)
    full = gmwm("WN+RW", x, freq=FREQ, seed=seed)
    pilot = gmwm("WN+RW", x[:n_pilot], freq=FREQ, seed=seed)
    own = LengthPredictor(full, law=law).predict(n / FREQ)
    pred = LengthPredictor(pilot, law=law).predict(n / FREQ)
    out = {"seed": seed}
    for k in ("N", "K"):
        est = getattr(own, k)
        out[k] = {"est": est, "ci": list(getattr(own, k + "_ci")), "pilot_pred_ci": list(getattr(pred, k + "_ci")),
                  "pilot_pred_value": getattr(pred, k)}
    return out


def summarise(rows: list[dict], z: float, rng: np.random.Generator) -> dict:
    truth = {"N": N_TRUE, "K": K_TRUE}
    res = {}
    for k in ("N", "K"):
        est = np.array([r[k]["est"] for r in rows])
        ci = np.array([r[k]["ci"] for r in rows])
        cov_own = int(np.sum((ci[:, 0] <= truth[k]) & (truth[k] <= ci[:, 1])))
        # the pilot's predicted log half-width for the full length, applied around the full-length estimate
        pv = np.array([r[k]["pilot_pred_value"] for r in rows])
        pci = np.array([r[k]["pilot_pred_ci"] for r in rows])
        h_pred = 0.5 * np.log(pci[:, 1] / pci[:, 0])
        h_own = 0.5 * np.log(ci[:, 1] / ci[:, 0])
        cov_pilot = int(np.sum(np.abs(np.log(est / truth[k])) <= h_pred))
        emp = z * float(np.std(np.log(est), ddof=1))
        boot = []
        for _ in range(2000):
            i = rng.integers(0, len(rows), len(rows))
            boot.append(float(np.median(h_pred[i])) / (z * float(np.std(np.log(est[i]), ddof=1))))
        n = len(rows)
        res[k] = {
            "truth": truth[k], "records": n,
            "coverage_own": cov_own / n, "coverage_own_ci95": wilson(cov_own, n),
            "coverage_pilot_width": cov_pilot / n, "coverage_pilot_width_ci95": wilson(cov_pilot, n),
            "median_half_width_own_pct": float(100 * np.median(np.expm1(h_own))),
            "median_half_width_pilot_pred_pct": float(100 * np.median(np.expm1(h_pred))),
            "empirical_half_width_pct": float(100 * math.expm1(emp)),
            "ratio_pilot_pred_to_empirical": float(np.median(h_pred)) / emp,
            "ratio_ci95": [float(np.percentile(boot, 2.5)), float(np.percentile(boot, 97.5))],
            "ratio_pilot_pred_to_own": float(np.median(h_pred) / np.median(h_own)),
            "bias_median_est_over_truth": float(np.median(est) / truth[k]),
            "pilot_value_over_truth_median": float(np.median(pv) / truth[k]),
        }
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed0", type=int, required=True)
    ap.add_argument("--records", type=int, default=100)
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--pilot-fraction", type=float, default=0.25)
    ap.add_argument("--law", choices=LAWS, default="model")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    n = int(round(a.hours * 3600 * FREQ))
    n_pilot = int(round(a.pilot_fraction * n))
    t0 = time.time()
    rows = [one(s, n, n_pilot, a.law) for s in range(a.seed0, a.seed0 + a.records)]
    z = float(norm.ppf(0.975))
    res = {"config": {"freq_hz": FREQ, "N_true": N_TRUE, "K_true": K_TRUE, "hours": a.hours,
                      "pilot_hours": a.hours * a.pilot_fraction, "law": a.law,
                      "seeds": [a.seed0, a.seed0 + a.records - 1]},
           "summary": summarise(rows, z, np.random.default_rng(a.seed0)), "elapsed_s": time.time() - t0,
           "records": rows}
    with open(a.out, "w") as fh:
        json.dump(res, fh, indent=1)
    for k, s in res["summary"].items():
        print(f"{k}: coverage at own length {100 * s['coverage_own']:.0f} % (Wilson 95 % "
              f"{100 * s['coverage_own_ci95'][0]:.0f}–{100 * s['coverage_own_ci95'][1]:.0f} %), median ±"
              f"{s['median_half_width_own_pct']:.2f} %; pilot ({a.hours * a.pilot_fraction:g} h) predicts ±"
              f"{s['median_half_width_pilot_pred_pct']:.2f} % at {a.hours:g} h vs empirical ±"
              f"{s['empirical_half_width_pct']:.2f} % (ratio {s['ratio_pilot_pred_to_empirical']:.3f}, "
              f"95 % CI {s['ratio_ci95'][0]:.3f}–{s['ratio_ci95'][1]:.3f}); full estimate ± pilot width covers "
              f"{100 * s['coverage_pilot_width']:.0f} %")


if __name__ == "__main__":
    main()
