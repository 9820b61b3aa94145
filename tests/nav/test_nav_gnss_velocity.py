"""GNSS velocity as a measurement (issue 23): it cuts the velocity error against the truth of a simulated drive,
and the batch and step filters apply it identically."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from imunoise.experiments.common import simulate_scenario
from imunoise.nav.aiding_sources import gnss_velocity_stream
from imunoise.nav.ekf import LooselyCoupledEKF, run_ekf
from imunoise.nav.measurements.gnss_velocity import as_gnss_velocity


@pytest.fixture(scope="module")
def drive():
    sc = simulate_scenario(2, duration_s=200, n_stops=0, n_outages=0, static_s=20, motion_noise="none")
    # velocity fixes with the position fixes (1 Hz): the antenna (lever 0) velocity + 5 cm/s white noise
    rng = np.random.default_rng(7)
    v = np.column_stack([np.interp(sc.gnss.t, sc.ref.t, sc.ref.vel_ned[:, i]) for i in range(3)])
    return sc, as_gnss_velocity(sc.gnss.t, v + rng.normal(0.0, 0.05, v.shape), 0.05)


def _vel_rms(res, sc) -> float:
    m = (sc.ref.t > res.t[0] + 30.0) & (sc.ref.t <= res.t[-1])
    i = np.searchsorted(res.t, sc.ref.t[m] - 1e-6)
    return float(np.sqrt(np.mean(np.sum((res.vel_ned[i] - sc.ref.vel_ned[m]) ** 2, axis=1))))


def test_gnss_velocity_reduces_velocity_error(drive):
    sc, vel = drive
    pos_only = run_ekf(sc.imu, sc.gnss, sc.init, sc.ekf_config())
    with_vel = run_ekf(sc.imu, sc.gnss, sc.init, sc.ekf_config(), streams=[gnss_velocity_stream(vel)])
    e0, e1 = _vel_rms(pos_only, sc), _vel_rms(with_vel, sc)
    assert e1 < 0.5 * e0, (e0, e1)  # measured: 0.349 → 0.065 m/s
    assert e1 < 0.1  # of the order of the fixes' 5 cm/s
    assert np.sum(with_vel.stream_status["gnss_velocity"] == 1) > 0.95 * np.sum(vel.t > sc.init.t)


def test_batch_and_step_agree_with_velocity_fixes(drive):
    sc, vel = drive
    t_all = sc.imu.t
    i0 = int(np.searchsorted(t_all, sc.init.t))
    init = replace(sc.init, t=float(t_all[i0]))
    cfg = sc.ekf_config()
    t_end = init.t + 60.0
    batch = run_ekf(sc.imu, sc.gnss, init, cfg, t_end=t_end, streams=[gnss_velocity_stream(vel)])
    dth, dv = sc.imu.increments()
    ekf = LooselyCoupledEKF(cfg, None, init, imu_rate_hz=sc.rate)
    ekf.prime(dth[i0], dv[i0])
    gi = int(np.searchsorted(sc.gnss.t, t_all[i0], side="right"))
    vi = int(np.searchsorted(vel.t, t_all[i0], side="right"))
    k = i0 + 1
    while t_all[k] <= t_end:
        ekf.propagate(dth[k], dv[k], t_all[k])
        while gi < sc.gnss.t.size and sc.gnss.t[gi] <= t_all[k]:
            ekf.update_gnss(sc.gnss.t[gi], sc.gnss.llh[gi], sc.gnss.sigma_ned[gi])
            gi += 1
        while vi < vel.t.size and vel.t[vi] <= t_all[k]:
            ekf.update_gnss_velocity(vel.t[vi], vel.vel_ned[vi], vel.sigma_ned[vi])
            vi += 1
        k += 1
    assert np.array_equal(batch.vel_ned[-1], ekf.view.vel) and np.array_equal(batch.llh[-1], ekf.view.llh)
    assert ekf.last_update.kind in ("gnss_position", "gnss_velocity")


def test_the_deprecated_gnss_vel_argument_warns_and_runs_the_stream_path(drive):
    """``run_ekf(gnss_vel=...)`` is kept for one release: it warns, names the replacement, and gives the
    trajectory and velocity statuses of ``streams=[gnss_velocity_stream(vel)]`` to the bit."""
    sc, vel = drive
    t_end = sc.init.t + 60.0
    new = run_ekf(sc.imu, sc.gnss, sc.init, sc.ekf_config(), t_end=t_end, streams=[gnss_velocity_stream(vel)])
    with pytest.warns(DeprecationWarning) as caught:
        old = run_ekf(sc.imu, sc.gnss, sc.init, sc.ekf_config(), t_end=t_end, gnss_vel=vel)
    text = str(caught[0].message)
    assert caught[0].filename == __file__  # points at the caller's line
    assert "streams=[gnss_velocity_stream(vel)]" in text and "from imunoise.nav import gnss_velocity_stream" in text
    for a, b in ((new.llh, old.llh), (new.vel_ned, old.vel_ned), (new.euler, old.euler), (new.std, old.std)):
        assert np.array_equal(a, b)
    assert np.array_equal(old.gnss_vel_status, new.stream_status["gnss_velocity"])
    assert np.array_equal(old.stream_status["gnss_velocity"], new.stream_status["gnss_velocity"])
    assert new.gnss_vel_status is None
