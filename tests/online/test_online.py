"""Online engine (docs/guide/theory.rst, 'Online engine'): streaming = batch, modelling events, latency, rejection, fit
→ filter mapping."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from imunoise.errors import DataError, ImunoiseError
from imunoise.experiments.common import simulate_scenario
from imunoise.noise.processes import AR1, QN, RW, WN
from imunoise.online import OnlineConfig, OnlineNavigator, ekf_axis_model
from imunoise.online.jobs import _implausible

FAST = "2*AR1 + WN + RW"  # small complete model: 11 candidates, keeps the tests fast


@pytest.fixture(scope="module")
def scenario():
    # 240 s drive: 30 s static start, two stops of 8–20 s, one 60 s outage
    return simulate_scenario(3, duration_s=240.0, n_stops=2, n_outages=1, static_s=30.0, stop_range_s=(8.0, 20.0))


def _config(sc, **kw):
    return OnlineConfig(ekf=sc.ekf_config(), complete=FAST, latency=0.0, **kw)


@pytest.fixture(scope="module")
def batch(scenario):
    sc = scenario
    return OnlineNavigator(_config(sc), sc.init, imu_rate_hz=sc.rate).run(sc.imu, sc.gnss.without(sc.windows))


def test_streaming_equals_batch(scenario, batch):
    """Acceptance 5: the streaming API and run() give the same trajectory (≤ 1e-9 m) on the same input,
    including λ0 learning, detection, identification, refits and model swaps."""
    sc = scenario
    gnss = sc.gnss.without(sc.windows)
    nav = OnlineNavigator(_config(sc), sc.init, imu_rate_hz=sc.rate)
    t, dth, dv = sc.imu.t, sc.imu.dtheta, sc.imu.dv
    gi = 0
    mid = None
    for k in range(t.size):
        while gi < gnss.t.size and gnss.t[gi] <= t[k]:
            nav.push_gnss(gnss.t[gi], gnss.llh[gi], gnss.sigma_ned[gi])
            gi += 1
        nav.push_imu(t[k], dth[k], dv[k])
        if k == t.size // 2:
            mid = nav.solution()
    stream = nav.finish()
    assert stream.t.shape == batch.t.shape
    np.testing.assert_array_equal(stream.t, batch.t)
    from imunoise.nav.earth import llh_to_ecef

    d = np.linalg.norm(llh_to_ecef(stream.llh) - llh_to_ecef(batch.llh), axis=1)
    assert d.max() <= 1e-9
    assert [e["event"] for e in stream.events] == [e["event"] for e in batch.events]
    # the mid-run solution is the stored epoch of that time
    k = int(np.searchsorted(batch.t, mid["t"]))
    assert np.allclose(mid["llh"], batch.llh[k], rtol=0, atol=1e-12)


def test_events_identify_then_refit(scenario, batch):
    ev = [e["event"] for e in batch.events]
    assert ev[0] == "start" and ev[-1] == "end"
    ident = [e for e in batch.events if e["event"] == "identified"]
    refits = [e for e in batch.events if e["event"] == "refit"]
    assert len(ident) == 1, "structure identification happens once"
    assert len(refits) == len(batch.segments) - 1
    # identification happens at the first stop with ≥ min_static_s of static data
    assert ident[0]["static_total_s"] >= 20.0
    assert set(ident[0]["axes"]) == {"gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"}
    for v in ident[0]["axes"].values():
        assert math.isfinite(v["gof"]) and v["time_s"] > 0 and v["structure"]
    # refits keep the structure of the identification
    for e in refits:
        for ax, v in e["axes"].items():
            assert v["structure"] == ident[0]["axes"][ax]["structure"]
    # latency 0: every swap happens at the stop's completion epoch
    swaps = [e for e in batch.events if e["event"] == "swap"]
    assert [s["t_stop"] for s in swaps] == [u.t_stop for u in batch.updates]
    for s in swaps:
        assert s["t"] == s["t_stop"]
    # the static segments lie inside the simulator's true static epochs (precision 1 on this drive)
    truth = scenario.static_truth
    for s in batch.segments:
        assert truth[s.i0:s.i1].all()
    json.dumps(batch.events)  # the event log is JSON-ready


def test_fixed_latency_delays_the_swap(scenario, batch):
    sc = scenario
    lat = 2.5
    r = OnlineNavigator(_config(sc).with_(latency=lat), sc.init, imu_rate_hz=sc.rate).run(
        sc.imu, sc.gnss.without(sc.windows))
    swaps = [e for e in r.events if e["event"] == "swap"]
    assert len(swaps) == len(batch.updates)
    for s in swaps:
        # the first IMU epoch at or after stop end + latency
        assert s["t_stop"] + lat <= s["t"] < s["t_stop"] + lat + 0.011
    # before the first swap the two runs are identical, after it they differ
    t_first = swaps[0]["t_stop"]
    k = int(np.searchsorted(r.t, t_first))
    assert np.array_equal(r.llh[:k], batch.llh[:k])
    assert not np.array_equal(r.llh, batch.llh)


def test_thread_worker_never_blocks_and_swaps(scenario):
    """worker="thread": the filter keeps taking samples while the model is computed; the model is used
    from the first sample after the thread finished. The replay is paced (sleeps) while a job runs, as
    the wall clock would be in live use."""
    import time

    sc = scenario
    cfg = _config(sc).with_(worker="thread", latency=None)
    nav = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate)
    gnss = sc.gnss
    gi = 0
    during = 0
    t, dth, dv = sc.imu.t, sc.imu.dtheta, sc.imu.dv
    for k in range(t.size):
        while gi < gnss.t.size and gnss.t[gi] <= t[k]:
            nav.push_gnss(gnss.t[gi], gnss.llh[gi], gnss.sigma_ned[gi])
            gi += 1
        t0 = time.perf_counter()
        nav.push_imu(t[k], dth[k], dv[k])
        if nav.modeller.busy:
            during += 1
            assert time.perf_counter() - t0 < 0.5  # a push never waits for the fit
            time.sleep(0.002)
    r = nav.finish()
    assert during > 0, "samples were processed while the model was being computed"
    swaps = [e for e in r.events if e["event"] == "swap"]
    assert swaps, "the background model reached the filter"
    ident = next(e for e in r.events if e["event"] == "identified")
    assert swaps[0]["t"] > ident["t"]  # used after the stop that triggered it, once computed
    assert np.all(np.isfinite(r.llh))


def test_plain_mode_has_no_modelling(scenario):
    sc = scenario
    r = OnlineNavigator(_config(sc).with_(modelling=False), sc.init, imu_rate_hz=sc.rate).run(sc.imu, sc.gnss)
    assert not r.updates and all(e["event"] not in ("identified", "swap") for e in r.events)
    assert len(r.segments) >= 2  # detection still runs (ZUPT, reports)


def test_gate_opens_in_fast_turns(scenario, batch):
    """Gate open exactly where |ω| > 30 °/s (docs/guide/theory.rst, 'Static detection'), with open/close events."""
    sc = scenario
    gyro, _ = sc.imu.rates()
    expect = np.linalg.norm(gyro, axis=1) > np.deg2rad(30.0)
    assert expect.any()
    np.testing.assert_array_equal(batch.gate_open, expect)
    n_open = sum(e["event"] == "gate_open" for e in batch.events)
    n_close = sum(e["event"] == "gate_closed" for e in batch.events)
    assert n_open >= 1 and n_open - n_close in (0, 1)


def test_zupt_holds_the_velocity_at_stops(scenario):
    sc = scenario
    runs = {}
    for z in (False, True):
        cfg = _config(sc).with_(modelling=False, zupt=z)
        runs[z] = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate).run(sc.imu, sc.gnss.without(sc.windows))
    r = runs[True]
    still = sc.static_truth[np.searchsorted(sc.imu.t, r.t)]
    speed = {z: np.linalg.norm(runs[z].vel_ned, axis=1)[still] for z in runs}
    assert np.sqrt(np.mean(speed[True] ** 2)) < np.sqrt(np.mean(speed[False] ** 2))
    # moving epochs are not zeroed
    assert np.median(np.linalg.norm(r.vel_ned, axis=1)[~still]) > 3.0


def test_push_imu_rejects_time_going_back(scenario):
    sc = scenario
    nav = OnlineNavigator(_config(sc), sc.init, imu_rate_hz=sc.rate)
    nav.push_imu(sc.imu.t[0], sc.imu.dtheta[0], sc.imu.dv[0])
    with pytest.raises(DataError):
        nav.push_imu(sc.imu.t[0], sc.imu.dtheta[0], sc.imu.dv[0])


def test_config_validation():
    with pytest.raises(ImunoiseError):
        OnlineConfig(criterion="aic")
    with pytest.raises(ImunoiseError):
        OnlineConfig(latency=-1.0)
    with pytest.raises(ImunoiseError):
        OnlineConfig(worker="process")


# -------------------------------------------------------------------------------------------------
# fit → filter mapping
# -------------------------------------------------------------------------------------------------
def test_fast_ar1_folds_into_white_noise_with_its_zero_frequency_density():
    f = 100.0
    phi, s2 = 0.9, 2e-6  # T_c = 0.095 s < fold_tau_s
    m = ekf_axis_model(AR1(phi=phi, sigma2=s2) + WN(sigma2=1e-6), f, None, fold_tau_s=1.0)
    assert str(m) == "WN"
    assert m.params["WN.sigma2"] == pytest.approx(1e-6 + s2 / (1 - phi) ** 2, rel=1e-12)
    # a slow AR1 stays a state with its parameters
    slow = ekf_axis_model(AR1(phi=0.9999, sigma2=1e-10) + WN(sigma2=1e-6), f, None)
    assert slow.params["AR1_1.phi"] == 0.9999 and slow.params["AR1_1.sigma2"] == 1e-10


def test_qn_white_or_dropped():
    m = QN(q2=3e-7) + WN(sigma2=1e-6)
    assert ekf_axis_model(m, 100.0, None, qn="white").params["WN.sigma2"] == pytest.approx(1e-6 + 6e-7)
    assert ekf_axis_model(m, 100.0, None, qn="drop").params["WN.sigma2"] == pytest.approx(1e-6)


def test_floor_bounds_white_rw_and_adds_the_slow_bias():
    f = 100.0
    floor = AR1(phi=math.exp(-1 / (3600 * f)), sigma2=1e-12) + WN(sigma2=1e-5) + RW(gamma2=1e-14)
    small = WN(sigma2=1e-7) + RW(gamma2=1e-16)
    m = ekf_axis_model(small, f, floor)
    assert m.params["WN.sigma2"] == 1e-5 and m.params["RW.gamma2"] == 1e-14
    assert m.n_ar1 == 1 and m.params["AR1_1.phi"] == floor.params["AR1_1.phi"]
    big = WN(sigma2=1e-3) + RW(gamma2=1e-10)
    m2 = ekf_axis_model(big, f, floor)
    assert m2.params["WN.sigma2"] == 1e-3 and m2.params["RW.gamma2"] == 1e-10


def test_implausible_fit_is_rejected(scenario, batch):
    fit = batch.fits[0]
    assert _implausible(fit, None) is None
    assert _implausible(fit, fit) is None
    # a "new" fit whose parameters are worse than the current ones on the same WV and Ω
    from dataclasses import replace

    worse_model = fit.model.with_vector(fit.model.vector * np.where(np.arange(fit.model.n_params) % 2, 3.0, 1.0))
    worse = replace(fit, model=worse_model, objective=fit.objective_at(worse_model))
    assert worse.objective > fit.objective
    reason = _implausible(worse, fit)
    assert reason is not None and "worse" in reason
    bad = replace(fit, objective=float("nan"))
    assert "non-finite" in _implausible(bad, None)


def test_non_finite_samples_never_crash_the_filter(scenario):
    """docs/guide/theory.rst, 'Quality bars': NaN IMU samples and NaN GNSS σ are logged and handled; the filter keeps
    running."""
    sc = scenario
    nav = OnlineNavigator(_config(sc).with_(modelling=False), sc.init, imu_rate_hz=sc.rate)
    t, dth, dv = sc.imu.t, sc.imu.dtheta.copy(), sc.imu.dv.copy()
    dth[500] = np.nan
    dv[9000, 1] = np.inf
    gi = 0
    for k in range(12000):
        while gi < sc.gnss.t.size and sc.gnss.t[gi] <= t[k]:
            sig = sc.gnss.sigma_ned[gi] if gi % 7 else np.full(3, np.nan)
            nav.push_gnss(sc.gnss.t[gi], sc.gnss.llh[gi], sig)
            gi += 1
        nav.push_imu(t[k], dth[k], dv[k])
    r = nav.finish()
    assert np.all(np.isfinite(r.llh)) and r.t.size > 11000


def test_swap_preserving_keeps_learned_states(scenario):
    from imunoise.nav.defaults import default_axis_models
    from imunoise.nav.ekf import LooselyCoupledEKF

    sc = scenario
    ekf = LooselyCoupledEKF(sc.ekf_config(), None, sc.init, imu_rate_hz=100.0)
    rng = np.random.default_rng(1)
    ekf.xm = rng.normal(0, 1e-3, ekf.xm.size)
    A = rng.normal(size=ekf.P.shape)
    ekf.P = ekf.P + 1e-8 * (A @ A.T)
    plain = default_axis_models(100.0)
    slow = list(plain)
    # first swap: plain (bias + slow GM) → slow GM + a new AR1 per axis: the slow GM state is kept
    new = [m + AR1(phi=0.99, sigma2=1e-8) for m in slow]  # the sum keeps the rate (100 Hz)
    x0, P0 = ekf.xm.copy(), ekf.P.copy()
    counts = ekf.swap_model(new, preserve=True, imu_rate_hz=100.0)
    assert counts == {"kept": 6, "reset": 6}
    L = ekf.layout
    for a in range(6):
        idx = L.index(a)
        gm = [i for i in idx if L.kind[i] == 1 and abs(np.diag(L.phi_pow[1])[i] - slow[a].params["AR1_1.phi"]) < 1e-15]
        assert len(gm) == 1
        assert ekf.xm[gm[0]] == x0[2 * a + 1]  # the old layout: [bias, GM] per axis
        assert ekf.P[9 + gm[0], 9 + gm[0]] == P0[9 + 2 * a + 1, 9 + 2 * a + 1]
    assert np.array_equal(ekf.P[:9, :9], P0[:9, :9])
    # a refit of the same structure keeps every state exactly
    x1, P1 = ekf.xm.copy(), ekf.P.copy()
    refit = [m + AR1(phi=0.995, sigma2=2e-8) for m in slow]
    assert ekf.swap_model(refit, preserve=True, imu_rate_hz=100.0) == {"kept": 12, "reset": 0}
    assert np.array_equal(ekf.xm, x1) and np.array_equal(ekf.P, P1)


def test_drift_maps_to_the_random_walk_with_the_same_wv_at_the_horizon():
    """DR → RW (dr="rw"): ν²_DR(τ_J) = ν²_RW(τ_J) exactly at the data's longest scale τ_J
    (docs/guide/theory.rst, 'Latent processes' closed forms)."""
    from imunoise.noise.processes import DR
    from imunoise.online import dr_equivalent_rw

    omega, tau = 2e-6, 4096.0
    g2 = dr_equivalent_rw(omega, tau)
    assert RW(gamma2=g2).wv(np.array([tau]))[0] == pytest.approx(DR(omega=omega).wv(np.array([tau]))[0], rel=1e-12)
    m = AR1(phi=0.999, sigma2=1e-8) + WN(sigma2=1e-6) + RW(gamma2=1e-12) + DR(omega=omega)
    out = ekf_axis_model(m, 100.0, None, horizon=tau)
    assert str(out) == "AR1 + WN + RW" and out.params["RW.gamma2"] == pytest.approx(1e-12 + g2)
    assert ekf_axis_model(m, 100.0, None, dr="drop").params["RW.gamma2"] == pytest.approx(1e-12)
    assert ekf_axis_model(m, 100.0, None, dr="state").has("DR")
    # without a horizon (a hand-written model, no data behind it) the drift stays the ramp the model states
    assert ekf_axis_model(m, 100.0, None).has("DR")
    with pytest.raises(ImunoiseError, match="dr must"):
        OnlineConfig(dr="ramp")


def test_ar1_slower_than_the_data_becomes_a_random_walk():
    """An AR1 with T_c·f beyond the data's longest scale maps to RW(γ² = its innovation σ²); without a horizon,
    or with T_c inside it, the AR1 stays a state."""
    slow = AR1(phi=math.exp(-1.0 / (100.0 * 3e5)), sigma2=1e-12)  # T_c = 3e5 s at 100 Hz
    m = slow + AR1(phi=0.999, sigma2=1e-8) + WN(sigma2=1e-6) + RW(gamma2=1e-13)
    out = ekf_axis_model(m, 100.0, None, horizon=2.0**13)
    assert str(out) == "AR1 + WN + RW"
    assert out.params["RW.gamma2"] == pytest.approx(1e-13 + 1e-12)
    assert out.params["AR1_1.phi"] == pytest.approx(0.999)
    assert str(ekf_axis_model(m, 100.0, None)) == "2*AR1 + WN + RW"
    assert str(ekf_axis_model(m, 100.0, None, horizon=2.0**40)) == "2*AR1 + WN + RW"


def test_collapsed_components_are_dropped():
    """A GOF-selected component at the parameter bound (σ² ~ 1e-57) is not made a filter state."""
    m = AR1(phi=0.999, sigma2=1e-60) + AR1(phi=0.99, sigma2=1e-9) + WN(sigma2=1e-6) + RW(gamma2=1e-58)
    out = ekf_axis_model(m, 100.0, None, fold_tau_s=0.5)
    assert str(out) == "AR1 + WN" and out.params["AR1_1.phi"] == 0.99


def test_cli_online_on_the_shipped_drive(tmp_path, capsys):
    """`imunoise online --data` resolves its inputs like `imunoise nav` and writes the
    docs/guide/theory.rst, 'Navigation filter' metrics."""
    import json
    from pathlib import Path

    from imunoise.cli import main

    data = Path(__file__).resolve().parents[2] / "data" / "drive_0708"
    assert main(["online", "--data", str(data), "--out", str(tmp_path)]) == 0
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["horizontal_rms_m"] < 0.05  # residual against the RTK that aids the filter
    assert (tmp_path / "events.jsonl").read_text().count("\n") >= 3
    # the "wrote" line names every file the run wrote (model.json included); the speed is given by both clocks
    cap = capsys.readouterr()
    wrote = next(line for line in cap.err.splitlines() if line.startswith("wrote "))
    files = sorted(p.name for p in tmp_path.iterdir() if p.is_file())
    assert "model.json" in files and sorted(Path(w).name for w in wrote[6:].split(", ")) == files
    assert "wall clock" in cap.out and "by CPU time" in cap.out
    assert metrics["cpu_s"] > 0 and metrics["cpu_realtime_factor"] == metrics["duration_s"] / metrics["cpu_s"]
    assert main(["online", "--imu", str(data / "imu_body_inc.txt.gz"), "--out", str(tmp_path / "x")]) == 2
    # a prior that is not there: a one-line error before anything is written
    assert main(["online", "--data", str(data), "--motion-noise-prior", str(tmp_path / "none.json"),
                 "--out", str(tmp_path / "y")]) == 2
    assert not (tmp_path / "y").exists()
