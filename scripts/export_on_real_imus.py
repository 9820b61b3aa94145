"""Exports on the five shared ADIS16405 logs (docs/evidence/export_on_real_imus.md): per axis the exported N
against the data's Allan deviation at T = 1 s (raw data, and the data with its narrowband lines removed), the
lines found, and on simulated broadband records what line removal changes.

Usage::

    # 1. per unit (K = 1..5): the command the evidence doc measures
    imunoise fit adis16405_unitK.npz --columns gyro_x=gyro_x,...,accel_z=accel_z --units gyro=deg/s,accel=g \\
        --auto --export kalibr --out OUT/unitK
    # 2. this script reads OUT/unitK/imu_model.json beside the data
    python scripts/export_on_real_imus.py --data ../shared/data/imudata_adis16405 --fits OUT
    python scripts/export_on_real_imus.py --simulate 6300000 --count 10
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

G = 9.80665
F = 100.0


def adev(y: np.ndarray, freq: float, tau: float) -> float:
    """Overlapping Allan deviation of the rate series ``y`` at averaging time ``tau`` [s]."""
    m = int(round(tau * freq))
    theta = np.concatenate([[0.0], np.cumsum(y)]) / freq
    d = theta[2 * m:] - 2 * theta[m:-m] + theta[:-2 * m]
    return math.sqrt(float(np.mean(d**2)) / (2 * tau**2))


def real(data: Path, fits: Path) -> None:
    from imunoise.export import axis_noise
    from imunoise.lines import remove_lines
    from imunoise.noise.allan import allan_variance, read_allan
    from imunoise.noise.imu_model import ImuModel

    worst = {"gyro": 0.0, "accel": 0.0, "accel_clean": 0.0, "accel_ieee": 0.0}
    for k in range(1, 6):
        d = np.load(data / f"adis16405_unit{k}.npz")
        X = d["data"]
        model = ImuModel.load(fits / f"unit{k}" / "imu_model.json")
        print(f"== unit {k} ==")
        for i, axis in enumerate(d["columns"]):
            axis = str(axis)
            y = X[:, i] * (math.pi / 180 if axis.startswith("gyro") else G)
            a = axis_noise(model.axes[axis], axis)
            raw = adev(y, F, 1.0)
            yc = remove_lines(y, F)[0]
            clean = adev(yc, F, 1.0)
            e_raw, e_clean = 100 * (a.N / raw - 1), 100 * (a.N / clean - 1)
            ieee = read_allan(allan_variance(yc, freq=F, grid="dense")).N
            e_ieee = 100 * (a.N / ieee - 1)
            s = "gyro" if axis.startswith("gyro") else "accel"
            worst[s] = max(worst[s], abs(e_raw))
            if s == "accel":
                worst["accel_clean"] = max(worst["accel_clean"], abs(e_clean))
                worst["accel_ieee"] = max(worst["accel_ieee"], abs(e_ieee))
            found = model.axes[axis].get("extra", {}).get("lines", {}).get("found", [])
            lines = ", ".join(f"{ln['freq_hz']:.3g} Hz {100 * ln['share']:.2g} %" for ln in found) or "none"
            print(f"  {axis:8s} {a.model:14s} N {a.N:.4e}  AD(1 s) raw {raw:.4e} ({e_raw:+.1f} %)  "
                  f"lines removed {clean:.4e} ({e_clean:+.1f} %)  IEEE -1/2 line {ieee:.4e} ({e_ieee:+.1f} %)  "
                  f"lines: {lines}")
    print(f"worst |N/AD(1 s) - 1|: gyro {worst['gyro']:.1f} % (raw AD), accel {worst['accel']:.1f} % (raw AD), "
          f"{worst['accel_clean']:.1f} % (AD of the line-free data), {worst['accel_ieee']:.1f} % (IEEE 952 "
          "white-noise line of the line-free data, imunoise.noise.allan.read_allan)")


def simulated(seed0: int, count: int) -> None:
    from imunoise.lines import remove_lines

    n = 2**20
    shares = []
    for seed in range(seed0, seed0 + count):
        rng = np.random.default_rng(seed)
        # ADIS16405-like gyro in rad/s: N 3.5e-3 rad/s/sqrt(Hz) (sigma 0.035 per sample), K 4e-5 rad/s^2/sqrt(Hz)
        x = 0.035 * rng.standard_normal(n) + np.cumsum(4e-5 / math.sqrt(F) * rng.standard_normal(n))
        if seed % 2:  # AR1 + WN + RW: a Gauss-Markov term with a 10 s correlation time
            from scipy.signal import lfilter

            phi = math.exp(-1 / (10 * F))
            x = x + lfilter([1.0], [1.0, -phi], 1e-3 * rng.standard_normal(n))
        y, found = remove_lines(x, F)
        removed = float(np.var(x - y) / np.var(x))
        shares.append(removed)
        print(f"seed {seed} ({'AR1+WN+RW' if seed % 2 else 'WN+RW'}): {len(found)} lines, variance removed "
              f"{100 * removed:.3g} %, data unchanged: {y is x}")
    print(f"largest share removed over {count} records: {100 * max(shares):.3g} %")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", type=Path)
    p.add_argument("--fits", type=Path)
    p.add_argument("--simulate", type=int, metavar="SEED")
    p.add_argument("--count", type=int, default=10)
    a = p.parse_args()
    if a.simulate is not None:
        simulated(a.simulate, a.count)
    if a.data is not None:
        real(a.data, a.fits)


if __name__ == "__main__":
    main()
