"""Every measurement's H against a numerical Jacobian: dz(x̂) − dz(x) ≈ H (x̂ − x), with the true state made
from the estimate by the filter's own feedback (so the test also pins the sign conventions)."""

from __future__ import annotations

import numpy as np
import pytest

from imunoise.nav.ekf_kernels import feedback
from imunoise.nav.measurements.gnss_position import gnss_position
from imunoise.nav.measurements.gnss_velocity import as_gnss_velocity, gnss_velocity
from imunoise.nav.measurements.nhc import nhc
from imunoise.nav.measurements.odometer import forward_speed, odometer
from imunoise.nav.measurements.zupt import zaru, zupt
from imunoise.nav.mechanization import make_nav
from imunoise.nav.state import I_DTH, N_NAV

NM = 6  # one bias state per axis
HVEC = np.ones(NM)
AXIS_OF = np.arange(NM, dtype=np.int64)


def _state(seed: int = 0):
    rng = np.random.default_rng(seed)
    nav = make_nav(np.array([0.7, -1.8, 1600.0]), np.array([9.0, -4.0, 0.3]), rng.uniform(-0.3, 0.3, 3) + [0, 0, 1.0])
    nav[I_DTH : I_DTH + 3] = rng.normal(0, 1e-3, 3)  # last corrected Δθ (ZARU)
    return nav, rng.normal(0, 1e-3, NM)


def _numerical_H(h, nav, xm, eps):
    """Column j: (h(x̂) − h(x̂ corrected by ε e_j)) / ε, i.e. ∂dz/∂δx_j."""
    n = N_NAV + NM
    z0 = h(nav, xm)
    J = np.zeros((z0.size, n))
    for j in range(n):
        nv, x = nav.copy(), xm.copy()
        dx = np.zeros(n)
        dx[j] = eps[j]
        feedback(nv, x, dx)
        J[:, j] = (z0 - h(nv, x)) / eps[j]
    return J


def _eps():
    return np.array([1e-3] * 3 + [1e-5] * 3 + [1e-7] * 3 + [1e-7] * NM)


MEASUREMENTS = {
    "gnss_position": lambda nav, xm: gnss_position(nav, N_NAV + NM, np.array([0.7, -1.8, 1600.5]),
                                                   np.array([0.3, -0.5, -1.2]), 0.0, np.ones(3)),
    "zupt": lambda nav, xm: zupt(nav, N_NAV + NM, 0.02),
    "gnss_velocity": lambda nav, xm: gnss_velocity(nav, N_NAV + NM, np.array([9.1, -3.9, 0.2]),
                                                   np.array([0.8, -0.5, -1.2]), 0.01, np.full(3, 0.05)),
    "nhc": lambda nav, xm: nhc(nav, N_NAV + NM, 0.1, 0.1),
    "odometer": lambda nav, xm: odometer(nav, N_NAV + NM, np.array([9.5]), np.array([-0.8, 0.4, 0.5]), 0.01,
                                         np.array([0.05, 0.01])),
}


def test_gnss_position_h_omits_the_velocity_term_of_late_fixes():
    # a fix δt before the filter epoch is referred with −v̂·δt, whose δv column (−δt·I) H leaves out: at
    # δt ≤ 1/rate (10 ms) a 1 % term of the velocity coupling (kept so, as the shipped trajectories)
    nav, xm = _state()
    f = lambda nv, x: gnss_position(nv, N_NAV + NM, np.array([0.7, -1.8, 1600.5]), np.zeros(3), 0.01, np.ones(3))  # noqa: E731
    J = _numerical_H(lambda nv, x: f(nv, x)[0], nav, xm, _eps())
    np.testing.assert_allclose(J[:, 3:6], -0.01 * np.eye(3), atol=1e-6)
    assert np.all(f(nav, xm)[1][:, 3:6] == 0.0)


@pytest.mark.parametrize("name", sorted(MEASUREMENTS))
def test_jacobian_matches_numerical(name):
    nav, xm = _state()
    f = MEASUREMENTS[name]
    _, H, R = f(nav, xm)
    J = _numerical_H(lambda nv, x: f(nv, x)[0], nav, xm, _eps())
    scale = np.maximum(np.abs(H), 1.0)
    np.testing.assert_allclose(H[:, :N_NAV], J[:, :N_NAV], atol=2e-4 * scale.max(), rtol=2e-3)
    assert np.all(np.diag(R) > 0)


def test_zaru_jacobian_is_the_gyro_model_coupling():
    # the corrected rate moves with the gyro model states only through the next increment's compensation, so
    # the ZARU H is the model coupling h_s (here the bias of each gyro axis), not a derivative of nav
    nav, xm = _state()
    dz, H, _ = zaru(nav, N_NAV + NM, 0.01, HVEC, AXIS_OF, 1e-3)
    expect = np.zeros((3, N_NAV + NM))
    expect[[0, 1, 2], [N_NAV, N_NAV + 1, N_NAV + 2]] = 1.0
    assert np.array_equal(H, expect)
    assert np.all(np.abs(dz - nav[I_DTH : I_DTH + 3] / 0.01) < 1e-4)  # minus the Earth rate (7.3e-5 rad/s)


def test_nhc_innovation_is_the_body_velocity():
    nav, xm = _state(3)
    from imunoise.nav.mechanization import nav_dcm

    dz, _, _ = nhc(nav, N_NAV + NM, 0.1, 0.1)
    vb = nav_dcm(nav).T @ nav[3:6]
    np.testing.assert_allclose(dz, vb[1:], atol=1e-12)


def test_gnss_velocity_lever_term():
    # a turning car: the antenna 1 m left of the IMU moves at ω × l on top of v
    nav, xm = _state()
    nav[I_DTH : I_DTH + 3] = [0.0, 0.0, 0.005]  # 0.5 rad/s yaw rate over 10 ms
    from imunoise.nav.mechanization import nav_dcm

    dz, _, _ = gnss_velocity(nav, N_NAV + NM, np.zeros(3), np.array([0.0, -1.0, 0.0]), 0.01, np.ones(3))
    expect = nav[3:6] + nav_dcm(nav) @ np.cross([0.0, 0.0, 0.5], [0.0, -1.0, 0.0])
    np.testing.assert_allclose(dz, expect, atol=1e-12)


def test_as_gnss_velocity_checks_and_floors():
    v = as_gnss_velocity([2.0, 1.0, np.nan], [[1, 2, 3], [4, 5, 6], [7, 8, 9]], [0.0, 0.1, 0.1])
    assert np.array_equal(v.t, [1.0, 2.0]) and np.array_equal(v.vel_ned[0], [4, 5, 6])
    assert np.all(v.sigma_ned[:, 0] == 0.005) and np.all(v.sigma_ned[:, 1] == 0.1)
    from imunoise.errors import DataError

    with pytest.raises(DataError, match="GNSS velocity: 2 times, 3 velocities"):
        as_gnss_velocity([1.0, 2.0], np.zeros((3, 3)), 0.1)


def test_odometer_innovation_is_the_forward_speed_of_the_wheel_point():
    from imunoise.nav.earth import dcm_to_euler
    from imunoise.nav.mechanization import nav_dcm

    nav, xm = _state(3)
    lever = np.array([-0.8, 0.4, 0.5])
    w = nav[I_DTH : I_DTH + 3] / 0.01
    dz, _, R = odometer(nav, N_NAV + NM, np.array([5.0]), lever, 0.01, np.array([0.05, 0.01]))
    vb = nav_dcm(nav).T @ nav[3:6] + np.cross(w, lever)
    np.testing.assert_allclose(dz + 5.0, vb[0], atol=1e-12)
    np.testing.assert_allclose(R[0, 0], 0.05**2 + (0.01 * vb[0]) ** 2, rtol=1e-12)  # the scale factor's share
    # the simulator's truth: the same forward axis from Euler angles
    euler = dcm_to_euler(nav_dcm(nav))
    np.testing.assert_allclose(forward_speed(nav[3:6][None], euler[None]), (nav_dcm(nav).T @ nav[3:6])[0],
                               atol=1e-12)


def test_a_kind_without_a_branch_raises_instead_of_reaching_another_function():
    # what a step sequence cached before a kind existed meets (numba's cache does not follow streams.py)
    from imunoise.nav.streams import make_stream, measure

    nav, _ = _state()
    st = make_stream("odometer", [1.0], [[5.0]], [[0.05, 0.01]], np.zeros(3))._replace(kind=99)
    with pytest.raises(ValueError, match="delete numba's cache"):
        measure(nav, N_NAV + NM, 0.01, st, 0, 1.0)
