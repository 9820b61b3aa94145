"""The filter's public update (filterpy's shape): a measurement given as (dz, H, R) is the same update as the
built-in one, to the bit."""

from __future__ import annotations

import numpy as np
import pytest

from imunoise.experiments.common import simulate_scenario
from imunoise.nav.ekf import LooselyCoupledEKF
from imunoise.nav.measurements.gnss_position import gnss_position


@pytest.fixture(scope="module")
def drive():
    """The simulated drive (read only): each test builds its own filters on it, so none depends on another."""
    return simulate_scenario(3, duration_s=120, n_stops=0, n_outages=0, static_s=10, motion_noise="none")


def _propagated(sc) -> LooselyCoupledEKF:
    """A fresh filter on ``sc`` after 15 s of propagation, the last one not on a covariance step."""
    dth, dv = sc.imu.increments()
    i0 = int(np.searchsorted(sc.imu.t, sc.init.t, side="right"))
    ekf = LooselyCoupledEKF(sc.ekf_config(), None, sc.init, imu_rate_hz=sc.rate)
    for k in range(i0, i0 + 1503):
        ekf.propagate(dth[k], dv[k], sc.imu.t[k])
    return ekf


@pytest.fixture
def two_filters(drive):
    return drive, [_propagated(drive), _propagated(drive)]


def test_update_with_dz_H_R_equals_the_builtin_update(two_filters):
    sc, (a, b) = two_filters
    g = int(np.searchsorted(sc.gnss.t, a.t)) - 1
    llh, sig = sc.gnss.llh[g], np.maximum(sc.gnss.sigma_ned[g], a.config.gnss_sigma_floor)
    assert a.update_gnss(sc.gnss.t[g], llh, sig)
    b.flush()  # (dz, H, R) of the state at the filter epoch, as update_gnss builds them
    dz, H, R = gnss_position(b.nav, b.P.shape[0], llh, b.lever, b.t - sc.gnss.t[g], sig)
    assert b.update(dz, H, R, chi2=b.config.chi2_gate, kind="gnss_position")
    assert np.array_equal(a.nav, b.nav) and np.array_equal(a.P, b.P) and np.array_equal(a.xm, b.xm)
    u = b.last_update
    assert u.kind == "gnss_position" and u.used and u.K.shape == (b.P.shape[0], 3)
    assert np.array_equal(u.S, a.last_update.S)


def test_update_rejects_by_chi2_unless_forced(drive):
    b = _propagated(drive)
    b.flush()  # the covariance at the filter epoch: a rejected update must leave exactly this
    n = b.P.shape[0]
    H = np.zeros((1, n))
    H[0, 3] = 1.0  # north velocity
    P0 = b.P.copy()
    assert not b.update([100.0], H, [[1e-4]], chi2=9.0)  # a 100 m/s innovation against cm/s uncertainty
    assert np.array_equal(b.P, P0) and b.last_update.nis > 9.0
    assert b.update([0.0], H, [[1e-4]], chi2=9.0) and b.P[3, 3] < P0[3, 3]
