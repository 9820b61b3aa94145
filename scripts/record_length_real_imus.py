"""How long to record on the five shared ADIS16405 logs (docs/evidence/record_length.md): per unit and axis the
precision of the exported N and K at the log's 2.8 h and the length a ±10 % K needs.

Usage::

    # 1. per unit (K = 1..5), the fit the README documents
    imunoise fit ../shared/data/imudata_adis16405/adis16405_unitK.npz \\
        --columns gyro_x=gyro_x,gyro_y=gyro_y,gyro_z=gyro_z,accel_x=accel_x,accel_y=accel_y,accel_z=accel_z \\
        --units gyro=deg/s,accel=g --auto --target 10 --out OUT/unitK
    # 2. this script reads OUT/unitK/imu_model.json
    python scripts/record_length_real_imus.py --fits OUT --target 10
    # 3. the check on the data themselves: each log cut in --split parts, each part refitted with the structure the
    #    whole log selected; the scatter of log K (and log N) across the parts against the width the whole log's
    #    fit predicts at the part's length
    python scripts/record_length_real_imus.py --fits OUT --data ../shared/data/imudata_adis16405 --split 4
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from imunoise.cli.record_length import axis_record_length, duration_text, line
from imunoise.export.record_length import LengthPredictor
from imunoise.noise.estimator import GMWMFit
from imunoise.noise.imu_model import ImuModel


def split_check(fits: Path, data: Path, parts: int) -> None:
    """Scatter of log N and log K across ``parts`` pieces of each log against the predicted log half-width /z."""
    from imunoise.lines import remove_lines
    from imunoise.noise.estimator import gmwm
    from imunoise.noise.fitting.length_covariance import record_length_s

    z = 1.959963984540054
    ratios: dict[str, list[float]] = {"N": [], "K": []}
    for k in range(1, 6):
        d = np.load(data / f"adis16405_unit{k}.npz")
        model = ImuModel.load(fits / f"unit{k}" / "imu_model.json")
        for i, axis in enumerate(str(c) for c in d["columns"]):
            y = d["data"][:, i] * (math.pi / 180 if axis.startswith("gyro") else 9.80665)
            y = remove_lines(y, 100.0)[0]  # as `fit` does before fitting
            full = GMWMFit.from_dict(model.axes[axis])
            pr = LengthPredictor(full)
            pred = pr.predict(record_length_s(full) / parts)
            est = {"N": [], "K": []}
            for part in np.array_split(y, parts):
                p = LengthPredictor(gmwm(str(full.model), part, freq=100.0, seed=k))
                for q in "NK":
                    est[q].append(p.values[q])
            row = [f"unit {k} {axis:<8}"]
            for q in "NK":
                lv = np.log(np.array(est[q]))
                se = math.log(getattr(pred, q + "_ci")[1] / getattr(pred, q)) / z
                if np.all(np.isfinite(lv)) and se > 0:
                    ratios[q].append(float(np.var(lv, ddof=1)) / se**2)
                    row.append(f"{q}: scatter/predicted {math.sqrt(ratios[q][-1]):.2f}")
            print("  ".join(row))
    for q in "NK":
        r = np.array(ratios[q])
        print(f"{q}: {r.size} axes; pooled scatter / predicted SD = {math.sqrt(r.mean()):.2f} (median per axis "
              f"{math.sqrt(np.median(r)):.2f}; per axis ratio² ~ χ²_{parts - 1}/{parts - 1} if the prediction holds)")


def _pct(v: float | None) -> str:
    return "bound" if v is None else f"{v:.2g}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fits", required=True, type=Path)
    ap.add_argument("--target", type=float, default=10.0)
    ap.add_argument("--data", type=Path, help="the logs: run the split check instead")
    ap.add_argument("--split", type=int, default=4)
    a = ap.parse_args()
    if a.data is not None:
        split_check(a.fits, a.data, a.split)
        return
    rows = []
    for k in range(1, 6):
        model = ImuModel.load(a.fits / f"unit{k}" / "imu_model.json")
        for axis, d in model.axes.items():
            fit = GMWMFit.from_dict(d)
            block = axis_record_length(fit, a.target)
            print(f"unit {k} {line(axis, block)}")
            at = block["at_record"]
            need = block["length_for_target_s"]["K"]
            need = float("nan") if need is None else float("inf") if need == "inf" else float(need)
            rows.append((k, axis, str(fit.model), at["N_pct"], at["K_pct"], duration_text(need)))
    print(f"\n| unit | axis | model | N ±% at 2.8 h | K ±% at 2.8 h | record for K ±{a.target:g} % |")
    print("|---|---|---|---|---|---|")
    for k, axis, m, n, kk, need in rows:
        print(f"| {k} | {axis} | {m} | {_pct(n)} | {_pct(kk)} | {need if kk is not None else '— (K a bound)'} |")


if __name__ == "__main__":
    main()
