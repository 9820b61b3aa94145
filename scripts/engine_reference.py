"""Fingerprints of the filter's trajectories, to show that a change of the filter engine keeps them to the bit.

Each case runs one path into the filter (the batch run on the shipped drive data/drive_0708 with NHC, ZUPT and
GNSS velocity; the batch run, a rehearsal and the sample-by-sample step filter on a simulated drive; the online
engine; the law-aware oracle's piecewise runs) and records the SHA-256 of every output array's bytes, so that
equal fingerprints mean equal trajectories to the last bit. ``python scripts/engine_reference.py --write``
stores them in tests/nav/data/engine_reference.json together with the CPU the numbers were made on (numba
compiles for the host CPU, so bit identity is a claim about one CPU and its features).
"""

from __future__ import annotations

import argparse
import hashlib
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
DRIVE = REPO / "data" / "drive_0708"
OUT = REPO / "tests" / "nav" / "data" / "engine_reference.json"
OLD_GATE = {"gate_abs": 0.0, "max_reject": -1}
"""The velocity gate the reference was made with (plain χ², never forced; the guards came after the engine)."""


def digest(a) -> str:
    a = np.ascontiguousarray(np.asarray(a))
    return hashlib.sha256(str(a.dtype).encode() + str(a.shape).encode() + a.tobytes()).hexdigest()[:32]


def host_cpu() -> str:
    import llvmlite.binding as llvm

    return f"{llvm.get_host_cpu_name()} {llvm.get_host_cpu_features().flatten()}"


def _prints(**arrays) -> dict[str, str]:
    return {k: digest(v) for k, v in arrays.items()}


def _result(res) -> dict[str, str]:
    d = _prints(t=res.t, llh=res.llh, vel=res.vel_ned, euler=res.euler, gyro=res.gyro_error, accel=res.accel_error,
                std=res.std, gnss_status=res.gnss_status, gnss_nis=res.gnss_nis)
    if res.stream_status.get("gnss_velocity") is not None:
        d["vel_status"] = digest(res.stream_status["gnss_velocity"])
    if res.cov is not None:
        d["cov"] = digest(res.cov)
    return d


def drive_case() -> dict:
    """The shipped drive, 200 s from the reference start: NHC, ZUPT over the first stop, RTK velocity."""
    from imunoise.io.dataset import read_dataset
    from imunoise.io.kfgins import read_gnss, read_imu
    from imunoise.nav.aiding_sources import gnss_velocity_stream
    from imunoise.nav.align import coarse_align
    from imunoise.nav.defaults import EkfConfig
    from imunoise.nav.ekf import run_ekf
    from imunoise.nav.measurements.gnss_velocity import as_gnss_velocity
    from imunoise.nav.measurements.nhc import NhcConfig

    ds = read_dataset(DRIVE)
    imu = read_imu(ds.imu, time_offset=ds.imu_time_offset_s)
    gnss = read_gnss(ds.gnss)
    v = np.loadtxt(DRIVE / "gnss_rtk_vel.txt")
    vel = as_gnss_velocity(v[:, 0], v[:, 1:4], v[:, 4:7], **OLD_GATE)
    init = coarse_align(imu, gnss, 243263.0, lever_arm=ds.lever_arm_m)
    cfg = EkfConfig(lever_arm=ds.lever_arm_m, aiding=(NhcConfig(),))
    zupt = np.asarray(imu.t) < init.t + 30.0
    out = {"nhc_zupt_vel": _result(run_ekf(imu, gnss, init, cfg, t_end=init.t + 200.0, zupt=zupt,
                                           streams=[gnss_velocity_stream(vel)], store_cov=True)),
           "plain": _result(run_ekf(imu, gnss, init, EkfConfig(lever_arm=ds.lever_arm_m), t_end=init.t + 200.0))}
    return out


def sim_case() -> dict:
    """A simulated 200 s drive: batch (NHC, ZUPT, velocity), a rehearsal, and the step filter sample by sample."""
    from imunoise.experiments.common import simulate_scenario
    from imunoise.nav.aiding_sources import gnss_velocity_stream
    from imunoise.nav.ekf import LooselyCoupledEKF, run_ekf
    from imunoise.nav.measurements.gnss_velocity import as_gnss_velocity
    from imunoise.nav.measurements.nhc import NhcConfig

    sc = simulate_scenario(2, duration_s=200, n_stops=2, n_outages=1, static_s=20, motion_noise="none")
    rng = np.random.default_rng(7)
    v = np.column_stack([np.interp(sc.gnss.t, sc.ref.t, sc.ref.vel_ned[:, i]) for i in range(3)])
    vel = as_gnss_velocity(sc.gnss.t, v + rng.normal(0.0, 0.05, v.shape), 0.05, **OLD_GATE)
    cfg = replace(sc.ekf_config(), aiding=(NhcConfig(),))
    gnss = sc.gnss.without(sc.windows)
    zupt = np.asarray(sc.imu.t) < sc.init.t + 15.0
    out = {"batch": _result(run_ekf(sc.imu, gnss, sc.init, cfg, zupt=zupt,
                                     streams=[gnss_velocity_stream(vel)]))}
    # the step filter, sample by sample (NHC inside propagate, fixes, velocity, ZUPT every 10 samples early on)
    t_all = sc.imu.t
    i0 = int(np.searchsorted(t_all, sc.init.t))
    init = replace(sc.init, t=float(t_all[i0]))
    dth, dv = sc.imu.increments()
    ekf = LooselyCoupledEKF(cfg, None, init, imu_rate_hz=sc.rate)
    ekf.prime(dth[i0], dv[i0])
    gi = int(np.searchsorted(gnss.t, t_all[i0], side="right"))
    vi = int(np.searchsorted(vel.t, t_all[i0], side="right"))
    pos, nis = [], []
    k = i0 + 1
    t_end = init.t + 120.0
    while t_all[k] <= t_end:
        ekf.propagate(dth[k], dv[k], t_all[k])
        while gi < gnss.t.size and gnss.t[gi] <= t_all[k]:
            ekf.update_gnss(gnss.t[gi], gnss.llh[gi], gnss.sigma_ned[gi])
            nis.append(ekf.last_update.nis)
            gi += 1
        while vi < vel.t.size and vel.t[vi] <= t_all[k]:
            ekf.update_gnss_velocity(vel.t[vi], vel.vel_ned[vi], vel.sigma_ned[vi], **OLD_GATE)
            nis.append(ekf.last_update.nis)
            vi += 1
        if t_all[k] < init.t + 15.0 and (k - i0) % 10 == 0:
            ekf.zupt_update(0.02, chi2=20.0)
        pos.append(np.concatenate([ekf.nav[:10], ekf.xm, np.diag(ekf.P)]))
        k += 1
    out["step"] = _prints(state=np.array(pos), nis=np.array(nis), P=ekf.P)
    # a rehearsal of the next 60 s from the step filter's state
    j = int(np.searchsorted(t_all, ekf.t))
    seg = slice(j, j + 6000)
    m = (gnss.t > t_all[j]) & (gnss.t <= t_all[seg][-1])
    r = ekf.rehearse(t_all[seg], dth[seg], dv[seg], gnss.t[m], gnss.llh[m], gnss.sigma_ned[m], with_nis=True,
                     with_std=True, with_nll=True)
    out["rehearse"] = _prints(**{f"r{i}": a for i, a in enumerate(r)})
    return out


def online_case() -> dict:
    """The online engine (chunks: NHC off, stops, ZUPT, swaps) on a simulated 200 s drive with an outage."""
    from imunoise.experiments.common import simulate_scenario
    from imunoise.online import OnlineConfig, OnlineNavigator

    sc = simulate_scenario(7, duration_s=200.0, n_stops=2, n_outages=1, outage_s=40.0, static_s=30.0,
                           stop_range_s=(8.0, 15.0))
    cfg = OnlineConfig(ekf=sc.ekf_config(), complete="2*AR1 + WN + RW", latency=0.3, zupt=True, stop_chi2=7.8)
    r = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate).run(sc.imu, sc.gnss.without(sc.windows))
    return {"zupt": _prints(t=r.t, llh=r.llh, vel=r.vel_ned, euler=r.euler, gyro=r.gyro_error, accel=r.accel_error,
                            std=r.std)}


def oracle_case() -> dict:
    """The law-aware oracle's piecewise runs (noise schedule) on a short simulated drive."""
    from imunoise.experiments.common import simulate_scenario
    from imunoise.experiments.oracle_law import run_windows_law

    sc = simulate_scenario(5, duration_s=240.0, n_stops=2, n_outages=0)
    res = run_windows_law(sc, sc.gnss, [(100.0, 40.0), (170.0, 30.0)])
    w = res["windows"]
    return {"windows": _prints(drift=np.array([x["drift"] for x in w], dtype=float),
                               rms=np.array([x["rms"] for x in w], dtype=float),
                               h=np.array([res["horizontal_rms_m"]], dtype=float))}


CASES = {"drive": drive_case, "sim": sim_case, "online": online_case, "oracle": oracle_case}


def fingerprints() -> dict:
    return {name: fn() for name, fn in CASES.items()}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--write", action="store_true", help=f"store the fingerprints in {OUT.relative_to(REPO)}")
    a = p.parse_args()
    fp = fingerprints()
    doc = {"cpu": host_cpu(), "cases": fp}
    if a.write:
        OUT.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
        print(f"wrote {OUT}")
    else:
        print(json.dumps(doc, indent=1, sort_keys=True))


if __name__ == "__main__":
    main()
