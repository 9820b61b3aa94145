"""The pair gate's tolerance (imunoise.export.gate.TOLERANCE): false refusals on in-family stop sets and power
on the departure-leak and vibration cases, each axis fitted as `calibrate` fits it (pooled stops,
imunoise.calibrate.fit.pooled_fit) and its exported pair gated (docs/evidence/export_on_real_imus.md).

Usage::

    python scripts/export_gate_power.py --seed 3700 --count 20
"""

from __future__ import annotations

import argparse
import math

import numpy as np

F = 100.0
N_TRUE = 1.0e-3       # m/s²/√Hz (σ 0.01 m/s² per sample)
K_TRUE = 2.0e-4       # m/s²/s/√Hz


def stops(rng: np.random.Generator, case: str) -> list[np.ndarray]:
    """Six stops of 20–60 s of accelerometer noise (WN + RW), bias removed per stop as calibrate does;
    ``leak``: the last 2 s of each stop are the start of a jerk-limited departure (0 → 0.5 m/s²);
    ``vibration``: an engine at idle, 31 Hz (amplitude 0.02 m/s², its own phase per stop)."""
    out = []
    for d in rng.uniform(20, 60, 6):
        n = int(d * F)
        x = N_TRUE * math.sqrt(F) * rng.standard_normal(n) + np.cumsum(K_TRUE / math.sqrt(F) * rng.standard_normal(n))
        t = np.arange(n) / F
        if case == "leak":
            s = np.clip((t - (d - 2.0)) / 2.0, 0.0, 1.0)
            x = x + 0.5 * s * s * (3 - 2 * s)
        elif case == "vibration":
            x = x + 0.02 * np.sin(2 * np.pi * 31.0 * t + rng.uniform(0, 2 * np.pi))
        out.append(x - x.mean())
    return out


def gate_of(segs: list[np.ndarray], seed: int):
    from imunoise.calibrate.fit import pooled_fit
    from imunoise.export import axis_noise
    from imunoise.export.gate import pair_gate

    fit = pooled_fit(segs, freq=F, unit="m/s²", seed=seed)
    a = axis_noise(fit, "accel_x")
    kept = list((fit.extra.get("lines") or {}).get("found", ()))
    return a, pair_gate(fit.wv, a.N, a.K, horizon_s=(a.tau_range_s or (None, None))[1], lines=kept)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seed", type=int, required=True)
    p.add_argument("--count", type=int, default=20)
    p.add_argument("--cases", default="family,leak,vibration")
    a = p.parse_args()
    for case in a.cases.split(","):
        refused, worst = 0, []
        for seed in range(a.seed, a.seed + a.count):
            ax, g = gate_of(stops(np.random.default_rng(seed), case), seed)
            refused += g.refused
            worst.append(g.best[2])
            print(f"{case} seed {seed}: {ax.model}: N {ax.N:.3e} K {ax.K:.3e}; {g.text()}")
        print(f"== {case}: refused {refused} of {a.count} axes; closest pair's worst factor median "
              f"{np.median(worst):.3g}, min {np.min(worst):.3g}, max {np.max(worst):.3g}")


if __name__ == "__main__":
    main()
