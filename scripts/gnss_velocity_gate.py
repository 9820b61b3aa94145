"""The GNSS velocity gate through the 60 s position outages of data/drive_0708 (outages_60s.txt): end-of-window
horizontal error of the IMU point against the RTK reference, with the drive's RTK velocity fixes (σ 4–6 cm/s)
through the outages, for velocity gates: none (χ² off for every update), the plain χ² gate (the old one), and the
χ² gate with the floor and forcing guards (the default), with and without NHC; and the velocity fixes rejected or
forced inside the windows. ``python scripts/gnss_velocity_gate.py``."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from imunoise.experiments.common import load_real, repo_data_dir
from imunoise.nav.aiding_sources import gnss_velocity_stream
from imunoise.nav.earth import radii
from imunoise.nav.ekf import run_ekf
from imunoise.nav.measurements.gnss_velocity import VEL_GATE_ABS, VEL_MAX_REJECT, as_gnss_velocity
from imunoise.nav.measurements.nhc import NhcConfig

GATES = {"plain chi2 (old)": {"gate_abs": 0.0, "max_reject": -1},
         f"chi2 + floor {VEL_GATE_ABS} m/s + forced after {VEL_MAX_REJECT}": {},
         "no chi2 gate at all": None}


def end_error(res, ref, t_end: float) -> float:
    k = int(np.searchsorted(ref.t, t_end)) - 1  # the last reference epoch inside the window (as `nav` reports it)
    j = int(np.searchsorted(res.t, ref.t[k] - 1e-6))
    rl = ref.llh[k]
    rm, rn = radii(rl[0])
    d = res.llh[j] - rl
    return float(np.hypot(d[0] * (rm + rl[2]), d[1] * (rn + rl[2]) * np.cos(rl[0])))


def main() -> None:
    sc = load_real(repo_data_dir())
    v = np.loadtxt(repo_data_dir() / "gnss_rtk_vel.txt")
    print("gate | NHC | end error per window (m) | mean (m) | velocity fixes rejected / forced in the windows")
    for name, gate in GATES.items():
        vel = as_gnss_velocity(v[:, 0], v[:, 1:4], v[:, 4:7], **(gate or {}))
        for nhc in (False, True):
            cfg = replace(sc.ekf_config(), aiding=(NhcConfig(),) if nhc else ())
            if gate is None:
                cfg = replace(cfg, chi2_gate=0.0)
            errs, rej, forced = [], [], []
            for s, length in sc.windows:
                r = run_ekf(sc.imu, sc.gnss.without([(s, length)]), sc.init, cfg, streams=[gnss_velocity_stream(vel)])
                errs.append(end_error(r, sc.ref, s + length))
                m = (vel.t >= s) & (vel.t < s + length)
                rej.append(int(np.sum(r.stream_status["gnss_velocity"][m] == 0)))
                forced.append(int(np.sum(r.stream_status["gnss_velocity"][m] == 2)))
            print(f"{name} | {'on' if nhc else 'off'} | {' '.join(f'{e:.2f}' for e in errs)} | {np.mean(errs):.2f} | "
                  f"{sum(rej)} / {sum(forced)}", flush=True)


if __name__ == "__main__":
    main()
