"""Measurement streams besides GNSS position in the online engine (GNSS velocity here; every registered kind takes
the same path, imunoise.online.measurement_feed): the same epochs applied with the same gate decisions as the batch
filter, the chunked replay equal to the per-sample pushes to the bit, and a velocity fix through an outage
keeping the drift down as `nav --gnss-vel` does."""

from __future__ import annotations

import numpy as np
import pytest

from imunoise.errors import DataError
from imunoise.experiments.common import run_filter, simulate_scenario
from imunoise.nav.ekf import run_ekf
from imunoise.nav.metrics import nav_errors
from imunoise.online import OnlineConfig, OnlineNavigator, run_online

ARRAYS = ("t", "llh", "vel_ned", "euler", "gyro_error", "accel_error", "std")


@pytest.fixture(scope="module")
def scenario():
    # 200 s drive: 30 s static start, two stops, one 40 s outage; GNSS velocity simulated from the truth (5 cm/s)
    return simulate_scenario(7, duration_s=200.0, n_stops=2, n_outages=1, outage_s=40.0, static_s=30.0,
                             stop_range_s=(8.0, 15.0), streams=("gnss_vel",))


def _push(nav, imu, gnss):
    gi = 0
    for k in range(imu.t.size):
        while gi < gnss.t.size and gnss.t[gi] <= imu.t[k]:
            nav.push_gnss(gnss.t[gi], gnss.llh[gi], gnss.sigma_ned[gi])
            gi += 1
        nav.push_imu(imu.t[k], imu.dtheta[k], imu.dv[k])
    return nav.finish()


def _end_error(res, sc) -> float:
    s, length = sc.windows[0]
    err = nav_errors(res.t, res.llh, res.vel_ned, res.euler, sc.ref)
    return float(err.horizontal[int(np.searchsorted(err.t, s + length)) - 1])


def test_online_applies_the_same_velocity_fixes_as_the_batch_filter(scenario):
    """Without modelling the online engine filters with the batch filter's models: every velocity fix gets the same
    status (used / rejected by the gate), and the trajectory agrees within what it does without the stream."""
    sc = scenario
    vel = sc.extra["streams"][0]
    gnss = sc.gnss.without(sc.windows)
    cfg = OnlineConfig(ekf=sc.ekf_config(), modelling=False)
    diffs = []
    for streams in ([], [vel]):
        nav = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate)
        if streams:
            nav.add_streams(*streams)
        on = nav.run(sc.imu, gnss)
        b = run_ekf(sc.imu, gnss, sc.init, sc.ekf_config(), streams=streams)
        diffs.append(float(np.max(np.abs(on.vel_ned - b.vel_ned[1:]))))
    st_on, st_b = nav.state.streams.status()["gnss_velocity"], b.stream_status["gnss_velocity"]
    assert np.array_equal(st_on, st_b)
    assert np.sum(st_on == 1) > 0.9 * vel.t.size  # the fixes were applied, not only counted
    assert diffs[1] <= max(2.0 * diffs[0], 1e-3), diffs  # m/s


def test_chunked_replay_equals_per_sample_pushes_with_a_velocity_stream(scenario):
    sc = scenario
    gnss = sc.gnss.without(sc.windows)
    cfg = OnlineConfig(ekf=sc.ekf_config(), complete="2*AR1 + WN + RW", latency=0.3)
    a = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate)
    a.add_streams(*sc.extra["streams"])
    ra = a.run(sc.imu, gnss)
    b = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate)
    b.add_streams(*sc.extra["streams"])
    rb = _push(b, sc.imu, gnss)
    for name in ARRAYS:
        assert np.array_equal(getattr(ra, name), getattr(rb, name)), name
    assert np.array_equal(a.state.streams.status()["gnss_velocity"], b.state.streams.status()["gnss_velocity"])
    assert "swap" in [e["event"] for e in ra.events]  # a model swap happened between the spans


def test_velocity_through_an_outage_reduces_the_online_drift(scenario):
    sc = scenario
    gnss = sc.gnss.without(sc.windows)
    cfg = OnlineConfig(ekf=sc.ekf_config(), latency=0.3)  # a fixed latency: the swaps at the same samples
    without = _end_error(run_online(sc.imu, gnss, sc.init, cfg), sc)
    with_vel = _end_error(run_online(sc.imu, gnss, sc.init, cfg, streams=sc.extra["streams"]), sc)
    assert with_vel < 0.3 * without, (with_vel, without)  # m at the end of the 40 s outage
    # the experiments' runs take the scenario's streams the same way
    r = run_filter(sc, cfg, windows=sc.windows)
    assert _end_error(r, sc) == with_vel


def test_streams_are_one_per_kind_and_never_gnss_position(scenario):
    sc = scenario
    nav = OnlineNavigator(OnlineConfig(ekf=sc.ekf_config()), sc.init, imu_rate_hz=sc.rate)
    vel = sc.extra["streams"][0]
    with pytest.raises(DataError, match="one per kind"):
        nav.add_streams(vel, vel)
    with pytest.raises(DataError, match="push_gnss"):
        nav.add_streams(vel._replace(kind="gnss_position"))
