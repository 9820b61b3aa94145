"""One door into the filter: a model file given to ``nav --imu-model`` / ``online --imu-model``
(:func:`imunoise.nav.defaults.load_axis_models`) and the online engine's own fits
(:func:`imunoise.online.to_filter.filter_axis_models`, the engine's ``filter_models``) build the same filter model,
for every registered process kind."""

from __future__ import annotations

import math

import pytest

from imunoise.imu import AXES
from imunoise.nav.defaults import load_axis_models
from imunoise.nav.filter_model import AxisFit, filter_axis_models, filter_model
from imunoise.noise.estimator import gmwm
from imunoise.noise.imu_model import ImuModel
from imunoise.noise.model import Model
from imunoise.noise.process_registry import PROCESS_TYPES
from imunoise.noise.processes import AR1, DR, MA1, QN, RW, SIN, WN
from imunoise.online import OnlineConfig
from imunoise.online.to_filter import filter_axis_models as engine_filter_models

RATE = 100.0
TRUTH = {  # one model per registered kind, that kind on top of white noise (AR1: one slow, one folded)
    "AR1": AR1(phi=0.9995, sigma2=4e-9) + AR1(phi=0.9, sigma2=1e-7) + WN(sigma2=1e-6),
    "WN": Model([WN(sigma2=1e-6)]),
    "QN": QN(q2=1e-7) + WN(sigma2=1e-6),
    "RW": RW(gamma2=1e-11) + WN(sigma2=1e-6),
    "DR": DR(omega=2e-8) + WN(sigma2=1e-6),
    "MA1": Model([MA1(theta=0.4, sigma2=1e-6)]),
    "SIN": SIN(alpha2=4e-6, beta=2 * math.pi * 31.0 / RATE) + WN(sigma2=1e-6),
}


def test_every_registered_kind_has_a_case():
    assert set(TRUTH) == set(PROCESS_TYPES)


@pytest.mark.parametrize("kind", sorted(PROCESS_TYPES))
def test_nav_model_file_and_online_engine_build_the_same_filter_model(kind, tmp_path):
    truth = TRUTH[kind]
    x = truth.simulate(2**15, seed=3800 + sorted(PROCESS_TYPES).index(kind))
    fits = {a: gmwm(truth.unknown(), x, freq=RATE, unit="rad/s" if a.startswith("gyro") else "m/s^2") for a in AXES}
    path = ImuModel.from_fits(fits).save(tmp_path / "model.json")
    nav_door = load_axis_models(str(path), RATE)  # nav --imu-model, online --imu-model
    stored = ImuModel.load(path)
    engine = engine_filter_models([stored.fit(a) for a in AXES], RATE, OnlineConfig(floor="none"))
    for m_nav, m_eng in zip(nav_door, engine, strict=True):
        assert m_nav.freq == m_eng.freq == RATE
        assert str(m_nav) == str(m_eng)
        assert m_nav == m_eng  # to the bit (Model.at_rate at the same rate is the model itself)
    assert not any(c.kind in ("DR", "QN", "MA1") for m in nav_door for c in m.components)  # not filter states


def test_drift_is_a_random_walk_with_a_horizon_and_a_ramp_without():
    """One decision for DR: the random walk with its WV at the data's longest scale when the fit carries it,
    the ramp state the model states when nothing says at which scale to match."""
    m = Model([DR(omega=1e-6), WN(sigma2=1e-4)])
    with_wv = filter_model(m, RATE, horizon=2.0**14)
    assert str(with_wv) == "WN + RW" and with_wv.params["WN.sigma2"] == 1e-4
    assert str(filter_model(m, RATE)) == "WN + DR"
    (mapped,) = filter_axis_models([AxisFit(m, RATE, None)], RATE, [None])
    assert mapped == Model([WN(sigma2=1e-4), DR(omega=1e-6)], RATE) and mapped.freq == RATE


def test_a_model_without_such_parts_passes_the_door_unchanged():
    """WN + RW + slow AR1s (every simulator truth and the plain default): the filter model is the model, to the
    bit, so those nav trajectories do not move."""
    m = Model([AR1(phi=0.9999, sigma2=1e-12), AR1(phi=0.999, sigma2=1e-10), WN(sigma2=3e-6), RW(gamma2=1e-14)])
    assert filter_model(m, RATE) == m
