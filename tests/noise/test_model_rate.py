"""A model carries the sample rate its per-sample parameters refer to: fits set it, the algebra keeps it and
refuses a sum of two rates, and every form that needs a rate takes it from the model or refuses with the fix
(docs/guide/theory.rst, 'Conventions')."""

from __future__ import annotations

import numpy as np
import pytest

from imunoise.errors import ModelError
from imunoise.noise.estimator import GMWMFit, gmwm
from imunoise.noise.model import Model
from imunoise.noise.processes import AR1, RW, WN


def _m(freq=None) -> Model:
    return Model([AR1(phi=0.99, sigma2=1e-8), WN(sigma2=1e-4)], freq)


def test_algebra_carries_the_rate():
    m = _m(200.0)
    assert (m + RW(gamma2=1e-12)).freq == 200.0
    assert (RW(gamma2=1e-12) + m).freq == 200.0  # a process has no rate: the model's is kept
    assert (2 * Model([AR1()], 200.0)).freq == (Model([AR1()], 200.0) * 2).freq == 200.0
    assert (m + Model([RW(gamma2=1e-12)])).freq == (Model([RW(gamma2=1e-12)]) + m).freq == 200.0
    assert (WN(sigma2=1.0) + RW(gamma2=1.0)).freq is None
    assert m.with_vector(m.vector * 0.5).freq == m.unknown().freq == m.scaled(2.0, 3.0).freq == 200.0
    assert m.with_params(m.params).freq == 200.0
    assert m.with_freq(None).freq is None and m.with_freq(100.0).vector.tolist() == m.vector.tolist()


def test_sum_of_two_rates_is_refused_with_the_conversion():
    with pytest.raises(ModelError, match=r"200 Hz.*100 Hz.*at_rate\(100, 200\)"):
        _m(200.0) + Model([RW(gamma2=1e-12)], 100.0)


def test_at_rate_checks_the_source_rate_and_carries_the_target():
    m = _m(200.0)
    down = m.at_rate(200.0, 100.0)
    assert down.freq == 100.0
    assert down.continuous()["WN.noise_density"] == pytest.approx(m.continuous()["WN.noise_density"], rel=1e-14)
    with pytest.raises(ModelError, match=r"at 200 Hz, not 100 Hz"):
        m.at_rate(100.0, 50.0)


def test_a_form_that_needs_a_rate_takes_the_models_or_refuses_with_the_fix():
    m = _m(200.0)
    assert m.continuous() == m.continuous(200.0) == _m().continuous(200.0)
    ss, want = m.state_space(0.01), _m().state_space(0.01, 200.0)
    assert np.array_equal(ss.Phi, want.Phi) and np.array_equal(ss.Q, want.Q) and ss.white_psd == want.white_psd
    with pytest.raises(ModelError, match=r"carries no sample rate.*with_freq\(rate_hz\)"):
        _m().continuous()
    with pytest.raises(ModelError, match=r"at 200 Hz, not 100 Hz.*at_rate\(200, 100\)"):
        m.continuous(100.0)
    with pytest.raises(ModelError, match=r"at 200 Hz, not 50 Hz"):
        m.state_space(0.01, 50.0)
    for bad in (0.0, -1.0, float("inf"), "100", True):
        with pytest.raises(ModelError, match="sample rate"):
            Model([WN(sigma2=1.0)], bad)


def test_a_fit_carries_its_rate_through_json():
    x = np.random.default_rng(8).normal(0.0, 1e-2, 4096)
    fit = gmwm(WN() + RW(), x, freq=250.0)
    assert fit.model.freq == 250.0
    back = GMWMFit.from_dict(fit.to_dict())
    assert back.model.freq == 250.0 and back.model == fit.model
    assert Model.from_dict({"model": "WN", "params": {"WN.sigma2": 1.0}, "freq_hz": 50.0}).freq == 50.0
    assert Model.from_dict({"model": "WN", "params": {"WN.sigma2": 1.0}}).freq is None


def test_equality_compares_rates_only_where_both_state_one():
    assert _m(200.0) == _m() and _m() == _m(100.0) and hash(_m(200.0)) == hash(_m())
    assert _m(200.0) != _m(100.0)
