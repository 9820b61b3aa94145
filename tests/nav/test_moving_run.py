"""The moving Gauss–Markov state of each axis is the one the door appended (its index, not its φ), even when the
static model already holds an AR1 of the same φ (docs/guide/theory.rst, 'In-use noise')."""

from __future__ import annotations

import math

import numpy as np

from imunoise.nav.defaults import EkfConfig
from imunoise.nav.ekf import LooselyCoupledEKF
from imunoise.nav.filter_model import in_motion_filter, moving_state_rows
from imunoise.nav.moving_run import moving_control
from imunoise.nav.state import N_NAV, InitialState
from imunoise.noise.model import Model
from imunoise.noise.processes import AR1, RW, WN

F = 100.0
TAU = 60.0
GM_SIGMA = 5.8e-4  # moving GM σ [rad/s]
STATIC_SIGMA = 2.0e-5  # σ of the static AR1 with the same φ [rad/s]


def _filter():
    phi = math.exp(-1.0 / (TAU * F))  # exactly the φ in_motion_filter computes for τ at F
    static_gx = Model([AR1(phi=phi, sigma2=STATIC_SIGMA**2 * (1 - phi * phi)), WN(sigma2=1e-7), RW(gamma2=1e-14)],
                      F)
    models = [static_gx] + [Model([WN(sigma2=1e-6)], F)] * 5
    sigma = [GM_SIGMA, 0, 0, 0, 0, 0]
    return phi, in_motion_filter(models, [3.0] * 6, sigma, [TAU] * 6)


def test_the_door_returns_the_appended_state_beside_an_equal_phi():
    phi, imf = _filter()
    m = imf.models[0]
    ar1 = [c for c in m.components if c.kind == "AR1"]
    assert len(ar1) == 2 and ar1[0].values[0] == ar1[1].values[0] == phi  # the ambiguous case: two equal φ
    k = imf.gm_index[0]
    moving = m.components[k]
    assert moving.kind == "AR1" and moving.values[1] == GM_SIGMA**2 * (1 - phi * phi)
    assert imf.gm_index[1:] == (-1,) * 5 and imf.gm_axes == (True,) + (False,) * 5


def test_moving_control_freezes_the_appended_state_not_the_static_one():
    _, imf = _filter()
    init = InitialState(0.0, np.array([0.5, 0.2, 10.0]), np.zeros(3), np.zeros(3))
    ekf = LooselyCoupledEKF(EkfConfig(), imf.models, init, imu_rate_hz=F)
    ctl = moving_control(ekf, imf)
    g = int(ctl.gm_index[0])
    assert np.all(ctl.gm_index[1:] == -1)
    labels = ekf.layout.labels
    assert np.array_equal(moving_state_rows(imf.models, imf.gm_index, labels), ctl.gm_index)  # the door's rows
    static = [i for i, lab in enumerate(labels) if lab.startswith("gyro_x.AR1_") and i != g]
    assert len(static) == 1
    s = static[0]
    # the state the control moves and freezes starts with the moving GM's variance, the other with the static one's
    P = np.asarray(ekf.P)
    np.testing.assert_allclose(P[N_NAV + g, N_NAV + g], GM_SIGMA**2, rtol=1e-12)
    np.testing.assert_allclose(P[N_NAV + s, N_NAV + s], STATIC_SIGMA**2, rtol=1e-12)
    # at a stop the moving state is frozen (φ = 1, no noise); the static AR1 of the same φ keeps evolving
    assert np.all(ctl.phi_frozen[1:, g, g] == 1.0) and np.all(ctl.q_frozen[:, g, g] == 0.0)
    assert np.all(ctl.phi_frozen[1:, s, s] < 1.0) and np.all(ctl.q_frozen[1:, s, s] > 0.0)
