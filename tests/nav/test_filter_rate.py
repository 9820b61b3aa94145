"""The filter takes models that carry their rate: a (model, freq) pair (deprecated, one release) and the model
at the same rate give the same filter to the bit; a model without a rate is refused with the fix
(docs/guide/theory.rst, 'Navigation filter')."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from imunoise.errors import ModelError
from imunoise.nav.defaults import EkfConfig, default_axis_models, normalize_axis_models
from imunoise.nav.ekf import InitialState, LooselyCoupledEKF
from imunoise.nav.error_states import ModelLayout
from imunoise.nav.filter_model import filter_axis_models, filter_model, in_motion_filter
from imunoise.noise.model import Model
from imunoise.noise.processes import AR1, DR, RW, WN

RATE = 200.0
LAYOUT = ("labels", "axis_of", "kind", "hvec", "P0", "phi_pow", "q_pow", "wpsd", "scale_index")


def _models() -> list[Model]:
    g = Model([AR1(phi=0.9995, sigma2=2e-13), WN(sigma2=3e-7), RW(gamma2=1e-15)], RATE)
    a = Model([AR1(phi=0.999, sigma2=1e-9), WN(sigma2=2e-5), DR(omega=1e-9)], RATE)
    return [g] * 3 + [a] * 3


def _pairs() -> list:
    return [(m.with_freq(None), RATE) for m in _models()]


def test_a_pair_and_the_model_at_its_rate_give_the_same_filter_to_the_bit():
    with pytest.warns(DeprecationWarning, match=r"pairs .* deprecated.*next release.*with_freq\(rate_hz\)"):
        from_pairs = normalize_axis_models(_pairs(), 100.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # models: no warning
        from_models = normalize_axis_models(_models(), 100.0)
    assert [m.freq for m in from_pairs] == [m.freq for m in from_models] == [RATE] * 6
    a, b = ModelLayout.build(from_pairs, 1.0 / RATE), ModelLayout.build(from_models, 1.0 / RATE)
    for name in LAYOUT:
        assert np.array_equal(np.asarray(getattr(a, name)), np.asarray(getattr(b, name))), name


def test_a_pair_and_a_model_run_the_same_trajectory():
    init = InitialState(0.0, np.array([0.7, -1.8, 100.0]), np.zeros(3), np.zeros(3), np.full(3, 1e-5))
    runs = []
    for given in (_pairs(), _models()):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            ekf = LooselyCoupledEKF(EkfConfig(), given, init, imu_rate_hz=RATE)
        rng = np.random.default_rng(11)
        for k in range(1, 601):
            ekf.propagate(rng.normal(0, 1e-6, 3), np.array([0.0, 0.0, -9.8 / RATE]) + rng.normal(0, 1e-5, 3),
                          k / RATE)
            if k % 100 == 0:
                ekf.update_gnss(k / RATE, init.llh + rng.normal(0, 1e-7, 3), np.full(3, 0.5))
        ekf.flush()
        runs.append((ekf.nav.copy(), ekf.xm.copy(), ekf.P.copy()))
    for x, y in zip(*runs, strict=True):
        assert np.array_equal(x, y)


def test_a_model_without_a_rate_is_refused_with_the_fix():
    bare = Model([WN(sigma2=1e-6), RW(gamma2=1e-14)])
    with pytest.raises(ModelError, match=r"carries no sample rate and the filter needs one.*with_freq\(rate_hz\)"):
        normalize_axis_models([bare] * 6, RATE)
    with pytest.raises(ModelError, match=r"carries no sample rate.*with_freq\(rate_hz\)"):
        filter_model(bare)
    with pytest.raises(ModelError, match=r"carries no sample rate"):
        in_motion_filter([bare] * 6, [1.0] * 6, [0.0] * 6, [1.0] * 6)
    # a pair whose rate contradicts the model's own
    with pytest.warns(DeprecationWarning), pytest.raises(ModelError, match=r"at 200 Hz, not 100 Hz"):
        normalize_axis_models([(m, 100.0) for m in _models()], RATE)


def test_the_door_and_the_defaults_give_models_with_their_rate():
    assert all(m.freq == RATE for m in default_axis_models(RATE))
    bare = Model([AR1(phi=0.9, sigma2=1e-8), WN(sigma2=1e-6)])
    assert filter_model(bare, RATE).freq == RATE == filter_model(bare.with_freq(RATE)).freq
    assert filter_model(bare, RATE) == filter_model(bare.with_freq(RATE))
    out = filter_axis_models([bare.with_freq(RATE), None], RATE, [None, default_axis_models(RATE)[1]])
    assert [m.freq for m in out] == [RATE, RATE]
    imf = in_motion_filter(_models(), [2.0] * 6, [1e-3] * 6, [5.0] * 6)
    assert all(m.freq == RATE for m in imf.models)
