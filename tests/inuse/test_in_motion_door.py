"""The in-motion part through the one door: absent → the static filter bit for bit; the true part of a simulated
drive under a moving Gauss–Markov law → the law-aware oracle's trajectory bit for bit, and a better likelihood
than the static model."""

from __future__ import annotations

import numpy as np
import pytest

from imunoise.imu import AXES
from imunoise.nav.ekf import run_ekf
from imunoise.nav.filter_model import in_motion_filter, in_motion_of


@pytest.fixture(scope="module")
def drive():
    from imunoise.experiments.common import filter_models, simulate_scenario
    from imunoise.noise.model import Model
    from imunoise.noise.processes import WN
    from imunoise.online import OnlineConfig

    sc = simulate_scenario(4702, duration_s=330.0, n_stops=2, motion_noise="gyro_moving_gm", n_outages=0)
    none = Model([WN(sigma2=1e-30)])
    cfg = OnlineConfig().with_(ekf=sc.ekf_config(), floor="none")
    pairs = filter_models([sc.extra["static_models"].get(ax, none) for ax in AXES], sc.rate, cfg)
    gyro, _ = sc.imu.rates()
    gate = ~(np.linalg.norm(gyro, axis=1) <= np.radians(30.0))  # the oracle's angular-rate gate
    return sc, pairs, gate


def test_model_without_part_takes_the_static_path(drive, tmp_path):
    sc, pairs, gate = drive
    assert in_motion_of({"kind": "imunoise.noise.imu_model", "axes": {}}, pairs) is None
    a = run_ekf(sc.imu, sc.gnss, sc.init, sc.ekf_config(), pairs, gate=gate)
    b = run_ekf(sc.imu, sc.gnss, sc.init, sc.ekf_config(), pairs, gate=gate, in_motion=None, moving=None)
    for x, y in ((a.llh, b.llh), (a.vel_ned, b.vel_ned), (a.euler, b.euler), (a.std, b.std)):
        assert np.array_equal(x, y)


def test_true_part_gives_the_oracle_law_trajectory_and_a_better_likelihood(drive):
    from imunoise.experiments.oracle_law import _drive_run

    sc, pairs, gate = drive
    sched = sc.extra["law_schedule"]
    oracle, _ = _drive_run(sc, sc.gnss)
    imf = in_motion_filter(pairs, [1.0] * 6, sched.gm_sigma, sched.gm_tau_s)
    r = run_ekf(sc.imu, sc.gnss, sc.init, sc.ekf_config(), in_motion=imf, moving=sched.moving, gate=gate,
                with_nll=True)
    assert np.array_equal(r.t, oracle.t)
    assert np.array_equal(r.llh, oracle.llh) and np.array_equal(r.vel_ned, oracle.vel_ned)
    static = run_ekf(sc.imu, sc.gnss, sc.init, sc.ekf_config(), pairs, gate=gate, with_nll=True)
    # the fixes are more likely under the true in-motion noise than under the static model (LR ≫ χ² threshold)
    assert 2.0 * (np.nansum(static.gnss_nll) - np.nansum(r.gnss_nll)) > 20.0
