"""A process owns its math: the registry is the one kind vocabulary, the numba forms the estimator runs equal
the numpy closed forms, a model moves between sample rates without changing its continuous-time meaning, and
the filter mapping keeps a fit's continuous-time N and K whatever the filter's rate."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from imunoise.noise.fitting.kernels import wv_and_jacobian, wv_of_theta
from imunoise.noise.fitting.params import KIND_CODE, kind_codes, theta_to_u, u_to_theta
from imunoise.noise.model import ORDER, Model
from imunoise.noise.processes import AR1, DR, PROCESS_TYPES, QN, RW, SIN, WN
from imunoise.online.config import OnlineConfig
from imunoise.online.to_filter import filter_axis_models

TAU = 2.0 ** np.arange(1, 22)
CASES = [
    WN(sigma2=3.7e-5), WN(sigma2=1.0), QN(q2=2.2e-9), QN(q2=0.4), RW(gamma2=1e-12), RW(gamma2=3.0),
    DR(omega=2e-7), DR(omega=-0.3), AR1(phi=0.5, sigma2=1e-3), AR1(phi=0.999, sigma2=2e-8),
    AR1(phi=1 - 1e-7, sigma2=1.0), AR1(phi=1e-3, sigma2=4.0),
    SIN(alpha2=4e-4, beta=1.9478), SIN(alpha2=2.0, beta=0.0314), SIN(alpha2=1e-9, beta=3.0),
]


def test_registry_is_the_one_kind_vocabulary():
    assert tuple(PROCESS_TYPES) == ORDER
    assert [cls.code for cls in PROCESS_TYPES.values()] == list(range(len(PROCESS_TYPES)))
    assert KIND_CODE == {k: cls.code for k, cls in PROCESS_TYPES.items()}
    m = Model.parse("2*AR1+WN+QN+RW+DR")
    assert kind_codes(m).tolist() == [AR1.code, AR1.code, WN.code, QN.code, RW.code, DR.code]


@pytest.mark.parametrize("proc", CASES, ids=repr)
def test_numba_form_equals_numpy_closed_form(proc):
    model = Model([proc])
    numpy_wv = proc.wv(TAU)
    nb = wv_of_theta(model.vector, kind_codes(model), TAU)
    np.testing.assert_allclose(nb, numpy_wv, rtol=1e-12, atol=0)
    # the estimator's u-form: the WV at θ(u) and its Jacobian against finite differences in u
    kinds = kind_codes(model)
    u = theta_to_u(model.vector, kinds, 1.0)
    theta = u_to_theta(u, kinds, 1.0)
    nu = np.empty(TAU.size)
    jac = np.empty((TAU.size, u.size))
    wv_and_jacobian(u, kinds, TAU, nu, jac)
    np.testing.assert_allclose(nu, model.with_vector(theta).wv(TAU), rtol=1e-11, atol=0)
    for k in range(u.size):
        # a line's WV ripples in β as fast as τ/4 at the coarsest scale (τ = 2^21): a finer step follows it
        h = 1e-8 if isinstance(proc, SIN) else 1e-6
        up, um = u.copy(), u.copy()
        up[k] += h
        um[k] -= h
        nup, num = np.empty(TAU.size), np.empty(TAU.size)
        wv_and_jacobian(up, kinds, TAU, nup, np.empty_like(jac))
        wv_and_jacobian(um, kinds, TAU, num, np.empty_like(jac))
        np.testing.assert_allclose(jac[:, k], (nup - num) / (2 * h), rtol=1e-5, atol=1e-9 * np.max(np.abs(nu)))


def test_at_rate_keeps_the_continuous_time_parameters():
    m = AR1(phi=0.999, sigma2=1e-8) + WN(sigma2=1e-5) + QN(q2=1e-9) + RW(gamma2=1e-12) + DR(omega=1e-9)
    c200 = m.continuous(200.0)
    c100 = m.at_rate(200.0, 100.0).continuous(100.0)
    assert c200.keys() == c100.keys()
    for k in c200:
        assert c100[k] == pytest.approx(c200[k], rel=1e-12), k
    assert m.at_rate(200.0, 200.0) == m and m.at_rate(200.0, 200.0).freq == 200.0  # the result carries its rate
    rated = m.with_freq(200.0)
    assert rated.at_rate(200.0, 200.0) is rated


def test_filter_gets_the_fits_continuous_noise_at_its_own_rate():
    """A 200 Hz fit fed to a 100 Hz filter keeps N and K (it used to get twice its white-noise density)."""
    fit_model = WN(sigma2=4e-6) + RW(gamma2=2.5e-13)
    fit = SimpleNamespace(model=fit_model, freq=200.0)
    cfg = OnlineConfig(floor="none")
    (model,) = filter_axis_models([fit], 100.0, cfg, floor=[None])
    assert model.freq == 100.0
    want, got = fit_model.continuous(200.0), model.continuous(100.0)
    assert got["WN.noise_density"] == pytest.approx(want["WN.noise_density"], rel=1e-12, abs=0)
    assert got["RW.random_walk"] == pytest.approx(want["RW.random_walk"], rel=1e-12, abs=0)
    # same rate: the per-sample model passes unchanged
    (same,) = filter_axis_models([SimpleNamespace(model=fit_model, freq=100.0)], 100.0, cfg, floor=[None])
    assert same.vector.tolist() == fit_model.vector.tolist()
    assert math.isclose(same.continuous(100.0)["WN.noise_density"], math.sqrt(4e-6 / 100.0), rel_tol=1e-15)


def test_state_space_roles_name_each_state():
    ss = (AR1(phi=0.9, sigma2=1.0) + WN(sigma2=1.0) + RW(gamma2=1.0) + DR(omega=1.0)).state_space(0.01, 100.0)
    assert ss.labels == ("bias", "AR1_1", "DR")
    assert ss.roles == (0, 1, 2)
    assert ss.Phi[0, 2] == 0.01 and ss.Q[0, 0] == 1.0
