"""How long to record on the five shared ADIS16405 logs (docs/evidence/record_length.md): per unit and axis the
precision of the exported N and K at the log's 2.8 h and the length a ±10 % K needs.

Usage::

    # 1. per unit (K = 1..5), the fit the README documents
    imunoise fit ../shared/data/imudata_adis16405/adis16405_unitK.npz \\
        --columns gyro_x=gyro_x,gyro_y=gyro_y,gyro_z=gyro_z,accel_x=accel_x,accel_y=accel_y,accel_z=accel_z \\
        --units gyro=deg/s,accel=g --auto --target 10 --out OUT/unitK
    # 2. this script reads OUT/unitK/imu_model.json
    python scripts/record_length_real_imus.py --fits OUT --target 10
"""

from __future__ import annotations

import argparse
from pathlib import Path

from imunoise.cli.record_length import axis_record_length, duration_text, line
from imunoise.noise.estimator import GMWMFit
from imunoise.noise.imu_model import ImuModel


def _pct(v: float | None) -> str:
    return "bound" if v is None else f"{v:.2g}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fits", required=True, type=Path)
    ap.add_argument("--target", type=float, default=10.0)
    a = ap.parse_args()
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
