"""Online engine in chunks (issue 25): run() = the per-sample push path to the bit, with stops, swaps, ZUPTs,
outages and extra event sources; the one 'next event' rule."""

from __future__ import annotations

import numpy as np
import pytest

import imunoise.nav.step_filter as step_filter
from imunoise.experiments.common import simulate_scenario
from imunoise.nav.filter_loop import next_event
from imunoise.nav.zupt_policy import static_runs
from imunoise.online import OnlineConfig, OnlineNavigator

FAST = "2*AR1 + WN + RW"
ARRAYS = ("t", "llh", "vel_ned", "euler", "gyro_error", "accel_error", "std", "gate_open", "static_raw", "sample_t")


@pytest.fixture(scope="module")
def scenario():
    # 200 s drive: 30 s static start, two stops, one 40 s outage
    return simulate_scenario(7, duration_s=200.0, n_stops=2, n_outages=1, outage_s=40.0, static_s=30.0,
                             stop_range_s=(8.0, 15.0))


def _config(sc, **kw):
    return OnlineConfig(ekf=sc.ekf_config(), complete=FAST, latency=0.3, **kw)


def _push(nav, imu, gnss):
    gi = 0
    for k in range(imu.t.size):
        while gi < gnss.t.size and gnss.t[gi] <= imu.t[k]:
            nav.push_gnss(gnss.t[gi], gnss.llh[gi], gnss.sigma_ned[gi])
            gi += 1
        nav.push_imu(imu.t[k], imu.dtheta[k], imu.dv[k])
    while gi < gnss.t.size:
        nav.push_gnss(gnss.t[gi], gnss.llh[gi], gnss.sigma_ned[gi])
        gi += 1
    return nav.finish()


def _events(r):
    drop = ("elapsed_s", "axes", "worker")
    return [{k: v for k, v in e.items() if k not in drop} for e in r.events if e["event"] != "warm_up"]


def _same(a, b):
    for name in ARRAYS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.shape == y.shape and np.array_equal(x, y), name
    assert _events(a) == _events(b)
    assert [(s.i0, s.i1) for s in a.segments] == [(s.i0, s.i1) for s in b.segments]
    assert [str(m) for m in a.final_models] == [str(m) for m in b.final_models]


@pytest.mark.timeout(900)
@pytest.mark.parametrize("zupt", [False, True])
def test_run_in_chunks_equals_per_sample_pushes(scenario, monkeypatch, zupt):
    """Stops (segments, stop guard), identification and refit swaps, an outage, ZUPT/ZARU: identical to the bit,
    and the kernel really ran spans (far fewer kernel calls than samples)."""
    sc = scenario
    gnss = sc.gnss.without(sc.windows)
    calls = []
    real = step_filter.run_steps

    def counting(*args):
        calls.append(args[0].t.size - 1)
        return real(*args)

    monkeypatch.setattr(step_filter, "run_steps", counting)
    cfg = _config(sc, zupt=zupt, stop_chi2=7.8 if zupt else 0.0)  # with ZUPT also the guard's NIS test
    batch = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate).run(sc.imu, gnss)
    assert sum(calls) > 0.8 * sc.imu.t.size and len(calls) < sc.imu.t.size / 20
    stream = _push(OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate), sc.imu, gnss)
    kinds = [e["event"] for e in batch.events]
    assert "swap" in kinds and "stop_end" in kinds
    _same(batch, stream)


@pytest.mark.timeout(900)
def test_event_sources_stop_the_kernel_at_their_samples(scenario):
    """An extra event source (a schedule's change points) is called before its samples with the filter at the
    previous sample, the same in run() and the push path; a hook that changes the filter changes both alike."""
    sc = scenario
    gnss = sc.gnss.without(sc.windows)
    points = np.array([3500, 5000, 5001, 9000, 17000])
    seen = {}
    for path in ("run", "push"):
        nav = OnlineNavigator(_config(sc).with_(modelling=False), sc.init, imu_rate_hz=sc.rate)
        log = seen.setdefault(path, [])

        def hook(n, i, log=log):
            log.append((i, n.ekf.t, n.ekf.nav.copy()))
            n.ekf.P[:3, :3] *= 4.0  # a noise bump: the rest of the run must follow it

        nav.add_event_source(points, hook)
        seen[path + "_res"] = nav.run(sc.imu, gnss) if path == "run" else _push(nav, sc.imu, gnss)
    assert [i for i, _, _ in seen["run"]] == points.tolist()
    for (i, t, x), (j, u, y) in zip(seen["run"], seen["push"], strict=True):
        assert i == j and t == u and t == sc.imu.t[i - 1] and np.array_equal(x, y)
    _same(seen["run_res"], seen["push_res"])


def test_next_event_is_the_earliest_source_at_or_after_k():
    src = [np.array([3, 10, 40]), np.array([], dtype=np.int64), np.array([7, 8])]
    assert next_event(0, 100, src) == 3
    assert next_event(4, 100, src) == 7
    assert next_event(9, 100, src) == 10
    assert next_event(11, 30, src) == 30  # nothing before the chunk's end
    assert next_event(41, 100, src) == 100


def test_static_runs_continue_the_previous_chunk():
    s = np.array([True, True, False, True, True, True, False])
    assert static_runs(s, 5).tolist() == [6, 7, 0, 1, 2, 3, 0]
    assert static_runs(np.array([True, True]), 0).tolist() == [1, 2]


@pytest.mark.timeout(900)
def test_run_in_chunks_with_the_motion_noise_learner(scenario):
    """gmwm_dyn: the shadows start at a fix sample and rehearse when due, a carried departure step is added at
    every start from a stop; identical to the push path."""
    from imunoise.online.learner import LearnedProcess, MotionNoisePrior
    from imunoise.online.motion_noise import MotionNoiseConfig

    sc = scenario
    gnss = sc.gnss.without(sc.windows)
    prior = MotionNoisePrior((LearnedProcess("step", "gyro", 5e-4), LearnedProcess("gm", "accel", 0.01, 100.0)))
    cfg = _config(sc, motion_noise=MotionNoiseConfig(every_s=10.0, outage_s=10.0, warm_rounds=0, choose_rounds=2,
                                                     confirm_rounds=2, alpha=0.9, margin=0.0, prior=prior))
    nav = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate)
    bumps = []
    orig = nav.learner.step

    def spy(nav_, t, dth, dvv, is_static, prev_run):
        if nav.learner.departure_due(prev_run, is_static):
            bumps.append(t)
        orig(nav_, t, dth, dvv, is_static, prev_run)

    nav.learner.step = spy
    batch = nav.run(sc.imu, gnss)
    stream = _push(OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate), sc.imu, gnss)
    assert any(e["event"] == "motion_noise_start" for e in batch.events)
    end = next(e for e in batch.events if e["event"] == "motion_noise_end")
    assert end["n_rehearsals"] >= 2
    assert len(bumps) >= 2  # both stops' departures took the carried step (the first after the static start too)
    _same(batch, stream)


@pytest.mark.timeout(900)
def test_push_chunk_equals_push_imu(scenario):
    """The streaming API in chunks (λ0 learned inside the first chunk, uneven chunk ends, fixes after a chunk's
    end queued) equals sample-by-sample pushes to the bit."""
    sc = scenario
    gnss = sc.gnss.without(sc.windows)
    cfg = _config(sc, zupt=True)
    nav = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate)
    t, dth, dv = sc.imu.t, sc.imu.dtheta, sc.imu.dv
    ends = [1500, 1501, 7000, 12345, t.size]
    a, gi = 0, 0
    for b in ends:
        gj = int(np.searchsorted(gnss.t, t[b - 1] + 0.5, side="right")) if b < t.size else gnss.t.size
        nav.push_chunk(t[a:b], dth[a:b], dv[a:b], gnss.t[gi:gj], gnss.llh[gi:gj], gnss.sigma_ned[gi:gj])
        a, gi = b, gj
    chunked = nav.finish()
    stream = _push(OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate), sc.imu, gnss)
    _same(chunked, stream)


def test_a_bad_fix_in_the_record_raises_where_push_gnss_would(scenario):
    """run() checks a record's fixes at once; a fix push_gnss refuses (here in degrees) still raises its error,
    when the replay reaches it (the samples before it are processed), and a good record is taken as checked."""
    from types import SimpleNamespace

    from imunoise.errors import DataError
    from imunoise.online.stream_checks import fixes_pass

    sc = scenario
    assert fixes_pass(sc.gnss.t, sc.gnss.llh, sc.gnss.sigma_ned)
    llh = np.array(sc.gnss.llh, dtype=float)
    k = llh.shape[0] // 2
    llh[k, :2] = np.degrees(llh[k, :2])
    bad = SimpleNamespace(t=sc.gnss.t, llh=llh, sigma_ned=sc.gnss.sigma_ned)
    assert not fixes_pass(bad.t, bad.llh, bad.sigma_ned)
    nav = OnlineNavigator(_config(sc).with_(modelling=False), sc.init, imu_rate_hz=sc.rate)
    with pytest.raises(DataError) as in_run:
        nav.run(sc.imu, bad)
    fresh = OnlineNavigator(_config(sc).with_(modelling=False), sc.init, imu_rate_hz=sc.rate)
    with pytest.raises(DataError) as pushed:
        fresh.push_gnss(bad.t[k], llh[k], bad.sigma_ned[k])
    assert str(in_run.value) == str(pushed.value) and "cannot be radians" in str(in_run.value)
    assert 0 < nav.state.t_last <= bad.t[k]


def test_collaborators_share_one_engine_state_and_a_fork_its_own(scenario):
    """The navigator's collaborators (detector feed, stop guard, ZUPT, learner host, modeller's event log) hold
    the navigator's one EngineState; a fork's collaborators hold the fork's copy, never the original's."""
    from imunoise.online.motion_noise import MotionNoiseConfig

    sc = scenario
    cfg = _config(sc, zupt=True, motion_noise=MotionNoiseConfig())
    nav = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate)
    n = sc.imu.t.size // 3
    dth, dv = sc.imu.increments()
    nav.push_chunk(sc.imu.t[:n], dth[:n], dv[:n])
    (br,) = nav.fork()
    for x in (nav, br):
        st = x.state
        assert x.feed.state is st and x.guard.state is st and x.zupt.state is st and x.learner.state is st
        assert x.modeller.events is st.events is x.events
        assert x.store is st.store
    assert br.state is not nav.state and br.state.rows is not nav.state.rows
    assert br.state.n_samples == nav.state.n_samples == n and br.state.rows[-1] is nav.state.rows[-1]
    assert br.store.n == 0 < nav.store.n  # the branch stores only its own epochs
    br.push_chunk(sc.imu.t[n:n + 100], dth[n:n + 100], dv[n:n + 100])
    assert br.state.n_samples == n + 100 and nav.state.n_samples == n
