"""First look at the scale-factor states on the real drive: the five official 60 s windows (one run each) and
full RTK, plain default model, without and with scale factors (three priors), plus the final estimates and
their posterior σ for the plain model and for online GMWM. Five windows cannot rank methods; this is a look.

    PYTHONPATH=src python scripts/scale_factors_first_look.py data/drive_0708
"""

from __future__ import annotations

import math
import sys

import numpy as np

from imunoise.io.dataset import read_dataset
from imunoise.io.kfgins import read_gnss, read_imu, read_outages, read_reference
from imunoise.nav.align import coarse_align
from imunoise.nav.defaults import EkfConfig, default_axis_models
from imunoise.nav.ekf import run_ekf
from imunoise.nav.metrics import nav_errors, summarize
from imunoise.online import OnlineConfig, OnlineNavigator


def main(data: str) -> None:
    ds = read_dataset(data)
    imu, gnss, ref = read_imu(str(ds.imu)), read_gnss(str(ds.gnss)), read_reference(str(ds.ref))
    windows = read_outages(str(ds.outages))
    t0, lever = float(ds.extra["start_sow"]), np.asarray(ds.lever_arm_m, dtype=float)
    init = coarse_align(imu, gnss, t0, static_duration=30.0, lever_arm=lever)
    models = default_axis_models(imu.rate_hz)
    base = EkfConfig(lever_arm=tuple(lever))
    sf = {"scale_factors": True, "scale_tau_s": math.inf}
    variants = {
        "off": base,
        "on, 1000 ppm GM 1 h (default)": base.with_(scale_factors=True),
        "on, 3000 ppm constant": base.with_(gyro_scale_std=3e-3, accel_scale_std=3e-3, **sf),
        "on, 10000 ppm constant": base.with_(gyro_scale_std=1e-2, accel_scale_std=1e-2, **sf),
    }
    for name, cfg in variants.items():
        r = run_ekf(imu, gnss, init, cfg, models)
        full = summarize(nav_errors(r.t, r.antenna_llh(lever), r.vel_ned, r.euler, ref), outages=[],
                         elapsed_s=r.elapsed_s, duration_s=1.0)
        ends = []
        for w in windows:
            rw = run_ekf(imu, gnss.without([w]), init, cfg, models)
            e = nav_errors(rw.t, rw.antenna_llh(lever), rw.vel_ned, rw.euler, ref)
            ends.append(summarize(e, outages=[w], elapsed_s=1.0, duration_s=1.0)["outages"][0]["end_horizontal_m"])
        s = "-" if r.scale_factors is None else np.round(r.scale_factors[-1] * 1e6).astype(int).tolist()
        print(f"{name:32s} end drift [m] {np.round(ends, 1).tolist()} mean {np.mean(ends):.1f}  "
              f"full RTK horizontal RMS {full['horizontal_rms_m']:.4f} m  ŝ [ppm] {s}")
    nav = OnlineNavigator(OnlineConfig(ekf=base.with_(scale_factors=True), latency=2.0), init,
                          imu_rate_hz=imu.rate_hz)
    nav.run(imu, gnss)
    nav.ekf.flush()
    idx = nav.ekf.layout.scale_index
    print("online GMWM (latency 2 s), full RTK: ŝ [ppm]", np.round(nav.ekf.scale_factors() * 1e6).astype(int).tolist(),
          "posterior σ [ppm]", np.round(np.sqrt(np.diag(nav.ekf.P)[9 + idx]) * 1e6).astype(int).tolist())


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "data/drive_0708")
