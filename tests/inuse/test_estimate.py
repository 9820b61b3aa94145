"""The in-motion estimate (maximum likelihood of the GNSS innovations over whole drives) against the simulator's
known motion law: a moving Gauss–Markov on the gyros is found and its truth lies in the intervals; without any
in-motion noise the wander is reported as a bound, with the reason, not as a number."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imunoise.imu import AXES
from imunoise.inuse import estimate_in_motion, summary_lines
from imunoise.inuse.estimate import WIDE_SD, _cov


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
    cov = _cov(H)
    assert math.isinf(cov[0, 0])  # curvature alone gives ×/÷ > 10: flat
    assert np.allclose(cov[1:, 1:], np.linalg.inv(H[1:, 1:]))
    assert np.all(np.isinf(_cov(np.diag([1.0 / WIDE_SD**2 / 2] * 3))))


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
        assert b.model == "gm", summary_lines(est.part)
        assert b.ci95["sigma"][0] <= sig <= b.ci95["sigma"][1]
        assert b.ci95["tau_s"][0] <= tau <= b.ci95["tau_s"][1]
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
