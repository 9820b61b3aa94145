"""The in-motion estimate (maximum likelihood of the GNSS innovations over whole drives) against the simulator's
known motion law: a moving Gauss–Markov on the gyros is found and its truth lies in the intervals; without any
in-motion noise the wander is reported as a bound, with the reason, not as a number."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imunoise.imu import AXES
from imunoise.inuse import estimate_in_motion, summary_lines
from imunoise.inuse.information import WIDE_SD, covariance


def _drive(seed: int, law: str):
    from imunoise.experiments.common import filter_models, simulate_scenario
    from imunoise.noise.model import Model
    from imunoise.noise.processes import WN
    from imunoise.online import OnlineConfig

    sc = simulate_scenario(seed, duration_s=600.0, motion_noise=law, n_outages=0)
    none = Model([WN(sigma2=1e-30)])
    cfg = OnlineConfig().with_(ekf=sc.ekf_config(), floor="none")
    return sc, filter_models([sc.extra["static_models"].get(ax, none) for ax in AXES], sc.rate, cfg)


def test_flat_parameters_are_left_out_of_the_covariance():
    H = np.array([[1e-3, 0.5, 0.0], [0.5, 50.0, 2.0], [0.0, 2.0, 1.0]])
    cov = covariance(H)
    assert math.isinf(cov[0, 0])  # curvature alone gives ×/÷ > 10: flat
    assert np.allclose(cov[1:, 1:], np.linalg.inv(H[1:, 1:]))
    assert np.all(np.isinf(covariance(np.diag([1.0 / WIDE_SD**2 / 2] * 3))))


def test_the_static_models_old_names_warn_and_hand_over_the_same_models():
    """``static_pairs`` and ``DriveLikelihood.pairs`` were renamed ``static_models`` / ``.models`` (they hold the
    six filter models with their rate, not pairs): the old names still answer for one release, with a warning."""
    from types import SimpleNamespace

    import imunoise.inuse as inuse
    from imunoise.inuse.likelihood import DriveLikelihood
    from imunoise.nav.defaults import default_axis_models

    six = default_axis_models(100.0)
    models = inuse.static_models(six, 100.0)
    assert [(m.to_dict(), m.freq) for m in models] == [(m.to_dict(), m.freq) for m in six]
    with pytest.warns(DeprecationWarning, match="renamed static_models"):
        old = inuse.static_pairs
    assert old is inuse.static_models
    lik = DriveLikelihood([SimpleNamespace(static_truth=np.zeros(4, dtype=bool))], models)
    with pytest.warns(DeprecationWarning, match=r"renamed \.models"):
        assert lik.pairs is lik.models is models
    with pytest.raises(AttributeError):
        _ = inuse.static_pairz


@pytest.mark.slow
def test_gyro_moving_gm_is_recovered_within_its_intervals():
    sc, models = _drive(4700, "gyro_moving_gm")
    sched = sc.extra["law_schedule"]
    sig, tau = float(sched.gm_sigma[0]), float(sched.gm_tau_s[0])
    est = estimate_in_motion([sc], models, freq=sc.rate, groups=("gyro",))
    assert est.lr_wander["gyro"] > 5.99
    for a in AXES[:3]:
        b = est.part.axes[a].bias
        assert b.model in ("gm", "rw"), summary_lines(est.part)
        if b.model == "gm":
            assert b.ci95["sigma"][0] <= sig <= b.ci95["sigma"][1]
            assert b.ci95["tau_s"][0] <= tau <= b.ci95["tau_s"][1]
        else:  # τ not identified once widened by the dispersion: the walk's k covers the GM's driving density
            assert b.ci95["k"][0] <= math.sqrt(2.0 * sig * sig / tau) <= b.ci95["k"][1]
        wf = est.part.axes[a].white_factor  # true factor 1: inside the interval, or under the bound
        assert wf.covers(1.0) if wf.value is not None else est.part.bounds[a].upper >= 1.0
    assert est.nll < est.nll_static


@pytest.mark.slow
def test_no_motion_noise_gives_a_bound_not_a_number():
    sc, models = _drive(4701, "none")
    est = estimate_in_motion([sc], models, freq=sc.rate, groups=("accel",))
    for a in AXES[3:]:
        ax = est.part.axes[a]
        assert ax.bias.model == "none" and ax.bias.sigma is None
        bd = est.part.bounds[a]
        assert bd.what == "bias" and "not distinguishable from none" in bd.reason
        assert bd.upper is not None and bd.upper > 0
        assert ax.white_factor.covers(1.0) if ax.white_factor.value is not None else True
    assert est.part.to_dict()["axes"]["accel_x"]["bias"] == {"model": "none", "ci95": {}}
    # a white factor that is not identified carries its likelihood bound in the evidence, the number in the text
    up = est.part.evidence["white_upper"]
    if est.part.axes["accel_x"].white_factor.value is None:
        assert up["accel"] is not None and up["accel"] >= 1.0
        assert f"≤ {up['accel']:.3g}" in est.part.bounds["accel_x"].reason
    else:
        assert "accel" not in up


@pytest.mark.slow
def test_a_white_factor_the_likelihood_does_not_reject_is_reported_as_1():
    """Law ``none`` on development vehicle 7 400 108's learning drive, with the static part the ``gmwm`` row fits at
    its stops: the gyro white factor's Wald interval at the optimum (about 2.3, interval 1.2–4.4) excludes 1, but
    twice the NLL difference at factor 1 is about 3.2 < χ²₁(0.95) = 3.84. The factor is reported as 1 with an
    interval that contains 1, the likelihood ratio in the evidence, and the filter runs with factor 1."""
    from dataclasses import replace

    from imunoise.experiments.carry_over import earlier_scenarios, learning_drives
    from imunoise.experiments.common import filter_models
    from imunoise.experiments.dense_warm import gmwm_on_drives
    from imunoise.experiments.gnss_regimes import parse_gnss
    from imunoise.inuse.estimate import LR_WHITE
    from imunoise.online import OnlineConfig

    seed, scen = 7_400_108, {"duration_s": 600.0, "n_stops": 4, "motion_noise": "none"}
    d = learning_drives(seed, 2, earlier_scenarios(seed, 1, **scen), parse_gnss("noise:1.5,3,1"), 1)
    base = OnlineConfig(latency=0.5)
    scs = [replace(sc, gnss=g) for sc, g in d]
    models = filter_models(list(gmwm_on_drives(d, base).fits), scs[0].rate, base.with_(ekf=scs[0].ekf_config()))
    est = estimate_in_motion(scs, models, freq=scs[0].rate)
    lr = est.part.evidence["lr_white_one"]
    assert 0.0 < lr["gyro"] < LR_WHITE
    for a in AXES[:3]:
        wf = est.part.axis(a).white_factor
        assert wf.value == 1.0 and wf.ci95 is not None and wf.ci95[0] <= 1.0 < wf.ci95[1]
    assert est.theta.white[:3] == (1.0, 1.0, 1.0) and est.part.white_factors()[:3] == [1.0, 1.0, 1.0]
