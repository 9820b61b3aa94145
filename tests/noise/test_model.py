"""Model algebra, canonical names, parsing, JSON and the filter state-space
(docs/guide/theory.rst, 'Latent processes' and 'Navigation filter')."""

from __future__ import annotations

import json

import numpy as np
import pytest

from imunoise import AR1, DR, QN, RW, WN, Model, ModelError
from imunoise.noise.model import default_complete


def test_algebra_and_str_round_trip():
    m = 2 * AR1() + WN() + RW()
    assert str(m) == "2*AR1 + WN + RW"
    assert Model.parse("2*AR1+WN+RW") == m
    assert Model.parse(str(m)) == m
    assert Model.parse("RW + WN + AR1() + AR1") == m  # order-free
    assert str(default_complete()) == "4*AR1 + WN + QN + RW + DR"
    assert default_complete().n_params == 12
    assert m.param_names == [
        "AR1_1.phi",
        "AR1_1.sigma2",
        "AR1_2.phi",
        "AR1_2.sigma2",
        "WN.sigma2",
        "RW.gamma2",
    ]


def test_ar1_sorted_slowest_first_and_names():
    m = AR1(phi=0.5, sigma2=1.0) + WN(sigma2=1.0) + AR1(phi=0.99, sigma2=2.0)
    assert m.params["AR1_1.phi"] == 0.99 and m.params["AR1_2.phi"] == 0.5
    assert m.params["AR1_1.sigma2"] == 2.0


@pytest.mark.parametrize("bad", ["", "2*AR2+WN", "WN++RW", "foo", "0*AR1"])
def test_parse_errors_list_processes(bad):
    with pytest.raises(ModelError) as exc:
        Model.parse(bad)
    assert "AR1" in str(exc.value) or "≥ 1" in str(exc.value)


def test_invalid_models():
    with pytest.raises(ModelError):
        WN() + WN()
    with pytest.raises(ModelError):
        AR1(phi=1.0, sigma2=1.0)
    with pytest.raises(ModelError):
        AR1(phi=0.5)
    with pytest.raises(ModelError):
        WN(sigma2=-1.0)
    with pytest.raises(ModelError):
        AR1(phi=0.5, sigma2=1.0) + WN()
    with pytest.raises(ModelError):
        (AR1() + WN()).with_params({"AR1_1.phi": 0.5})


def test_wv_is_sum_of_components_and_json_round_trip():
    m = AR1(phi=0.99, sigma2=1e-4) + WN(sigma2=1.0) + QN(q2=0.1) + RW(gamma2=1e-6) + DR(omega=1e-5)
    tau = 2.0 ** np.arange(1, 12)
    np.testing.assert_allclose(m.wv(tau), np.sum(list(m.component_wv(tau).values()), axis=0), rtol=1e-15)
    back = Model.from_dict(json.loads(json.dumps(m.to_dict())))
    assert back == m
    assert back.params == m.params


def test_state_space_blocks():
    f = 100.0
    m = (
        AR1(phi=0.999, sigma2=1e-8)
        + AR1(phi=0.9, sigma2=1e-6)
        + WN(sigma2=1e-4)
        + RW(gamma2=1e-10)
        + QN(q2=1e-5)
        + DR(omega=1e-9)
    )
    ss = m.state_space(0.01, f)
    assert ss.labels == ("bias", "AR1_1", "AR1_2", "DR")
    np.testing.assert_allclose(np.diag(ss.Phi), [1.0, 0.999, 0.9, 1.0])
    assert ss.Phi[0, 3] == pytest.approx(0.01)
    assert ss.Q[0, 0] == pytest.approx(1e-10)
    assert ss.Q[1, 1] == pytest.approx(1e-8)  # σ²_GM(1−φ²) = σ² at the native step
    assert ss.P0[2, 2] == pytest.approx(1e-6 / (1 - 0.81))
    np.testing.assert_allclose(ss.H, [1, 1, 1, 0])
    assert ss.white_psd == pytest.approx((1e-4 + 2e-5) / f)
    # A step of k native samples is the k-fold composition of the AR1 transition.
    ss5 = m.state_space(0.05, f)
    assert ss5.Phi[1, 1] == pytest.approx(0.999**5)
    assert ss5.Q[1, 1] == pytest.approx(sum(1e-8 * 0.999 ** (2 * i) for i in range(5)))
    assert ss5.Q[0, 0] == pytest.approx(5e-10)


def test_state_space_stationary_variance_matches_simulation():
    m = AR1(phi=0.95, sigma2=1e-2) + WN(sigma2=1e-3)
    ss = m.state_space(1.0)
    x = m.simulate(400_000, seed=1)
    predicted = ss.P0[1, 1] + ss.white_var
    assert abs(x.var() / predicted - 1) < 0.05
