"""The online engine's outputs on a fixed set of runs, saved and compared exactly: a refactoring of the engine
(e.g. its composition into named collaborators around one engine state) must leave them identical to the bit.

    PYTHONPATH=OLD/src python scripts/online_engine_identity.py run before.pkl    # with the code before
    PYTHONPATH=NEW/src python scripts/online_engine_identity.py run after.pkl     # with the code after
    python scripts/online_engine_identity.py compare before.pkl after.pkl

Runs (from the repository root, which holds ``data/drive_0708``): a simulated 200 s drive (seed 7, two stops, one
40 s outage) through ``run`` (default, ZUPT with the guard's NIS test, λ0 learned, the in-motion noise learner),
through ``push_imu``/``push_gnss`` (ZUPT, λ0 learned), through ``push_chunk`` with a ``fork`` half way; the
dense-window protocol on that drive (30 s windows; ``plain``, ``gmwm``, ``static_var``, ``av_online``: the
experiments' stored-epoch errors, forks and λ0 learning); the real drive (five 60 s outages; default and ZUPT) and
its dense windows with ``gmwm``. Saved: every per-epoch array of the results, the events, the segments, the final
models, λ0, and the window metrics. A fixed ``latency`` everywhere: with ``latency=None`` a model takes effect
after its measured compute time, which differs from run to run. Compared: everything exactly (NaN = NaN), except
the compile/warm-up timings of the ``warm_up`` event. About 5 minutes per ``run`` on one core.
"""

from __future__ import annotations

import sys

import numpy as np
from identity_harness import run_or_compare

ARRAYS = ("t", "llh", "vel_ned", "euler", "gyro_error", "accel_error", "std", "gate_open", "static_raw", "sample_t")
TIMING = ("time_s", "compiled", "loaded", "already", "kernels")  # warm-up timings, not outputs
FAST = "2*AR1 + WN + RW"


def pack(r):
    d = {n: getattr(r, n) for n in ARRAYS}
    d["events"] = [{k: v for k, v in e.items() if k not in ("elapsed_s", "worker")} for e in r.events]
    d["segments"] = [(s.i0, s.i1) for s in r.segments]
    d["models"] = [str(m) for m in r.final_models]
    d["lambda0"] = r.lambda0
    return d


def push(nav, imu, gnss):
    gi = 0
    for k in range(imu.t.size):
        while gi < gnss.t.size and gnss.t[gi] <= imu.t[k]:
            nav.push_gnss(gnss.t[gi], gnss.llh[gi], gnss.sigma_ned[gi])
            gi += 1
        nav.push_imu(imu.t[k], imu.dtheta[k], imu.dv[k])
    return nav.finish()


def run() -> dict:
    from imunoise.experiments.common import load_real, simulate_scenario
    from imunoise.experiments.dense import DenseSpec, dense_windows, evaluate_method
    from imunoise.online import OnlineConfig, OnlineNavigator
    from imunoise.online.learner.config import MotionNoiseConfig

    out = {}
    sc = simulate_scenario(7, duration_s=200.0, n_stops=2, n_outages=1, outage_s=40.0, static_s=30.0,
                           stop_range_s=(8.0, 15.0))
    g = sc.gnss.without(sc.windows)
    base = OnlineConfig(ekf=sc.ekf_config(), complete=FAST, latency=0.3)
    learner = MotionNoiseConfig(every_s=10.0, outage_s=10.0, warm_rounds=0, choose_rounds=2)
    for name, cfg in {"sim": base, "sim_zupt": base.with_(zupt=True, stop_chi2=7.8),
                      "sim_nolam": base.with_(detector=None),
                      "sim_learn": base.with_(motion_noise=learner)}.items():
        out[name] = pack(OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate).run(sc.imu, g))
        print(name, flush=True)
    for name, cfg in {"sim_push_zupt": base.with_(zupt=True), "sim_push_nolam": base.with_(detector=None)}.items():
        out[name] = pack(push(OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate), sc.imu, g))
    # push_chunk + fork
    nav = OnlineNavigator(base.with_(detector=None), sc.init, imu_rate_hz=sc.rate)
    dth, dv = sc.imu.increments()
    t = sc.imu.t
    n = t.size // 2
    gt = np.asarray(g.t)
    k = int(np.searchsorted(gt, t[n - 1], side="right"))
    nav.push_chunk(t[:n], dth[:n], dv[:n], gt[:k], g.llh[:k], g.sigma_ned[:k])
    br, = nav.fork()
    br.push_chunk(t[n:], dth[n:], dv[n:], gt[k:], g.llh[k:], g.sigma_ned[k:])
    nav.push_chunk(t[n:], dth[n:], dv[n:])
    out["sim_fork_branch"] = pack(br.finish())
    out["sim_fork_main"] = pack(nav.finish())
    print("fork", flush=True)
    # dense windows (the experiments' stored-epoch errors, forks, λ0 learning)
    ws = dense_windows(sc, DenseSpec(length_s=30.0, step_s=30.0, lead_s=40.0))
    print("windows", ws, flush=True)
    for m in ("plain", "gmwm", "static_var", "av_online"):
        out["dense_" + m] = evaluate_method(sc, m, sc.gnss, ws, base=OnlineConfig(ekf=sc.ekf_config(), latency=0.5))
        print(m, flush=True)
    # real drive
    rd = load_real("data/drive_0708")
    rg = rd.gnss.without(rd.windows)
    rbase = OnlineConfig(ekf=rd.ekf_config(), latency=1.0)
    for name, cfg in {"real": rbase, "real_zupt": rbase.with_(zupt=True)}.items():
        out[name] = pack(OnlineNavigator(cfg, rd.init, imu_rate_hz=rd.rate).run(rd.imu, rg))
        print(name, flush=True)
    rws = dense_windows(rd, DenseSpec())
    out["real_dense_gmwm"] = evaluate_method(rd, "gmwm", rd.gnss, rws, base=rbase)
    print("real dense", flush=True)
    return out


def same(x, y, path: str) -> None:
    if isinstance(x, dict):
        assert set(x) == set(y), (path, set(x) ^ set(y))
        for k in x:
            same(x[k], y[k], f"{path}.{k}")
    elif isinstance(x, list | tuple):
        assert len(x) == len(y), path
        for i, (u, v) in enumerate(zip(x, y, strict=True)):
            same(u, v, f"{path}[{i}]")
    elif isinstance(x, np.ndarray):
        assert x.shape == y.shape and np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), path
    elif isinstance(x, float) and x != x:
        assert y != y, path
    elif path.rsplit(".", 1)[-1] not in TIMING:
        assert x == y, (path, x, y)


def main(argv: list[str]) -> int:
    return run_or_compare(argv, run, same, __doc__)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
