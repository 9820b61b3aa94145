"""Error-state layout and model swap as pure functions; one antenna-position function for both results
(docs/guide/theory.rst, 'Navigation filter')."""

from __future__ import annotations

import numpy as np
import pytest

from imunoise.errors import DataError
from imunoise.nav.defaults import EkfConfig, default_axis_models
from imunoise.nav.ekf import EkfResult, InitialState, LooselyCoupledEKF
from imunoise.nav.error_states import ModelLayout, carried_states, initial_covariance, swap_map
from imunoise.nav.solution import antenna_llh
from imunoise.noise.model import Model
from imunoise.noise.processes import AR1, DR, RW, WN

RATE = 100.0


def _layout(models) -> ModelLayout:
    return ModelLayout.build([m.with_freq(RATE) for m in models], 1.0 / RATE)


def _random_state(layout: ModelLayout, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    n = 9 + layout.nm
    A = rng.normal(size=(n, n))
    return rng.normal(0, 1e-3, layout.nm), A @ A.T * 1e-6 + np.eye(n) * 1e-8


def test_swap_map_reset_keeps_navigation_and_total_error():
    plain = default_axis_models(RATE)  # bias + slow GM per axis
    old = _layout(plain)
    new = _layout([Model([AR1(phi=0.99, sigma2=1e-8), WN(sigma2=1e-6), DR(omega=1e-9)])] * 6)
    x, P = _random_state(old, 1)
    P0 = initial_covariance(EkfConfig(), new)
    res = swap_map(old, new, x, P, P0, preserve=False)
    assert (res.kept, res.reset) == (0, 12)  # an AR1 and a DR per axis start fresh
    assert np.array_equal(res.P[:9, :9], P[:9, :9])
    for a in range(6):
        io, inew = old.index(a), new.index(a)
        h = old.hvec[io]
        b = inew[0]
        assert res.x[b] == pytest.approx(h @ x[io], rel=1e-15)  # the axis' total error estimate
        assert res.P[9 + b, 9 + b] == pytest.approx(h @ P[np.ix_(9 + io, 9 + io)] @ h, rel=1e-12)
        np.testing.assert_allclose(res.P[9 + b, :9], P[np.ix_(9 + io, np.arange(9))].T @ h, rtol=1e-12)
        for s in inew[1:]:  # fresh: zero estimate, uncorrelated, variance from the new initial P
            assert res.x[s] == 0.0
            assert np.count_nonzero(res.P[9 + s]) == 1 and res.P[9 + s, 9 + s] == P0[9 + s, 9 + s]
    assert np.array_equal(res.P, res.P.T)


def test_swap_map_preserve_carries_states_over_exactly():
    plain = default_axis_models(RATE)
    assert plain[0].params["AR1_1.phi"] > 0.995  # the added AR1s below differ from the slow GM
    old = _layout(plain)
    new = _layout([m + AR1(phi=0.99, sigma2=1e-8) for m in plain])
    pairs = carried_states(old, new)
    assert len(pairs) == 6
    for s_new, s_old in pairs.items():  # the slow GM continues itself, matched by φ
        assert old.kind[s_old] == new.kind[s_new] == 1 and old.axis_of[s_old] == new.axis_of[s_new]
        assert np.diag(new.phi_pow[1])[s_new] == pytest.approx(np.diag(old.phi_pow[1])[s_old])
    x, P = _random_state(old, 2)
    res = swap_map(old, new, x, P, initial_covariance(EkfConfig(), new))
    assert (res.kept, res.reset) == (6, 6)
    for s_new, s_old in pairs.items():
        assert res.x[s_new] == x[s_old]
        assert res.P[9 + s_new, 9 + s_new] == P[9 + s_old, 9 + s_old]
        np.testing.assert_array_equal(res.P[9 + s_new, :9], P[9 + s_old, :9])
    # a refit of the same structure (other parameters) keeps every state and the whole covariance
    refit = _layout([m + AR1(phi=0.995, sigma2=2e-8) for m in plain])
    again = swap_map(new, refit, res.x, res.P, initial_covariance(EkfConfig(), refit))
    assert (again.kept, again.reset) == (12, 0)
    assert np.array_equal(again.x, res.x) and np.array_equal(again.P, res.P)


def test_ekf_swap_model_is_swap_map_on_its_state():
    init = InitialState(0.0, np.array([0.7, -1.8, 100.0]), np.zeros(3), np.zeros(3), np.full(3, 1e-5))
    cfg = EkfConfig()
    ekf = LooselyCoupledEKF(cfg, None, init, imu_rate_hz=RATE)
    old, x, P = ekf.layout, ekf.xm.copy(), ekf.P.copy()
    models = [Model([AR1(phi=0.999, sigma2=1e-10), WN(sigma2=1e-6), RW(gamma2=1e-14)], RATE)] * 6
    counts = ekf.swap_model(models, preserve=True, imu_rate_hz=RATE)
    ref = swap_map(old, ekf.layout, x, P, initial_covariance(cfg, ekf.layout), preserve=True)
    assert counts == {"kept": ref.kept, "reset": ref.reset}
    assert np.array_equal(ekf.xm, ref.x) and np.array_equal(ekf.P, ref.P)
    np.testing.assert_allclose(ekf.sensor_errors()[:3], 1e-5, rtol=1e-12)  # the bias estimate survives


def test_add_bias_variance_touches_only_the_bias_diagonal():
    init = InitialState(0.0, np.array([0.7, -1.8, 100.0]), np.zeros(3), np.zeros(3))
    ekf = LooselyCoupledEKF(EkfConfig(), None, init, imu_rate_hz=RATE)
    ekf.propagate(np.full(3, 1e-5), np.array([0.0, 0.0, -0.098]), 0.01)
    ekf.flush()
    P = ekf.P.copy()
    var = np.array([1e-10, 0.0, 2e-10, -1.0, np.nan, 3e-6])  # ≤ 0 and NaN add nothing
    ekf.add_bias_variance(var)
    rows = [9 + int(ekf.layout.index(a)[0]) for a in range(6)]
    expect = P.copy()
    expect[rows, rows] += [1e-10, 0.0, 2e-10, 0.0, 0.0, 3e-6]
    assert np.array_equal(ekf.P, expect)


def test_prime_only_before_the_first_increment():
    init = InitialState(0.0, np.array([0.7, -1.8, 100.0]), np.zeros(3), np.zeros(3))
    ekf = LooselyCoupledEKF(EkfConfig(), None, init, imu_rate_hz=RATE)
    ekf.prime(np.full(3, 1e-5), np.array([0.0, 0.0, -0.098]))
    ekf.propagate(np.full(3, 1e-5), np.array([0.0, 0.0, -0.098]), 0.01)
    with pytest.raises(DataError, match="before the first propagate"):
        ekf.prime(np.zeros(3), np.zeros(3))


def test_batch_and_online_results_share_one_antenna_function():
    from imunoise.online import OnlineResult

    rng = np.random.default_rng(5)
    n = 30
    llh = np.column_stack([rng.uniform(0.6, 0.8, n), rng.uniform(-2, -1.8, n), rng.uniform(0, 2000, n)])
    eul = rng.uniform(-1, 1, (n, 3))
    z = np.zeros((n, 3))
    lever = [1.2, -0.7, -1.5]
    batch = EkfResult(np.arange(n), llh, z, eul, z, z, np.zeros((n, 9)), np.zeros(0), np.zeros(0), np.zeros(0))
    online = OnlineResult(np.arange(n), llh, z, eul, z, z, np.zeros((n, 9)), [], [], [], np.zeros(0, bool),
                          np.zeros(0, bool), 0.0, 0.0, [])
    expect = antenna_llh(llh, eul, lever)
    assert np.array_equal(batch.antenna_llh(lever), expect)
    assert np.array_equal(online.antenna_llh(lever), expect)
    assert np.array_equal(antenna_llh(llh, eul, [0, 0, 0]), llh)
