"""``oracle_const`` (the constant-model ceiling of the in-use family, :mod:`imunoise.experiments.oracle_const`): its
constant model is the law's time-average over the drive's moving samples, computed here by hand from the simulator's
per-sample schedule; under a law that the family holds exactly (a moving Gauss–Markov) it is ``oracle_law``'s filter;
and the row runs end to end in the dense-window protocol. Development seed 7 400 098 (and 7 400 097)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imunoise.experiments import dense
from imunoise.experiments.common import simulate_scenario
from imunoise.experiments.oracle_const import constant_in_motion, true_static_models


def _moving(sc) -> np.ndarray:
    """The filter's samples (from the last IMU sample at or before sc.init.t) where the vehicle moves."""
    i0 = int(np.searchsorted(np.asarray(sc.imu.t), sc.init.t, side="right")) - 1
    return i0, ~np.asarray(sc.static_truth, dtype=bool)[i0:]


def test_constant_model_is_the_laws_moving_average_on_drive0708():
    sc = simulate_scenario(7400098, duration_s=240.0, n_stops=1, n_outages=0, motion_noise="drive0708")
    pairs = true_static_models(sc)
    c = constant_in_motion(sc, pairs)
    sched = sc.extra["law_schedule"]
    i0, mv = _moving(sc)
    f = sc.rate
    assert c.moving_s == pytest.approx(mv.sum() / f, abs=0)
    assert 0 < c.moving_s < 240.0
    mw2 = sched.white_var_scale[i0:][mv].mean(axis=0)
    mb2 = sched.bias_var_scale[i0:][mv].mean(axis=0)
    assert mw2[0] > 1.5 and mb2[2] > 1.5  # the law acts at speed: the averages are not trivially 1
    # the code and this test may sum the moving samples in another order (numpy's pairwise sums depend on the
    # CPU's vector width): a mean of n terms agrees to n·eps, a few operations after it to a few eps more
    tol = 4.0 * float(mv.sum()) * float(np.finfo(float).eps)
    for a in range(6):
        true_w = sc.extra["static_models"][("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")[a]]
        w_true = true_w.white_variance() / f
        w_filter = pairs[a].white_variance() / f
        # the white PSD while moving: the true white × ⟨m_w²⟩ plus the folded short AR1 noise × ⟨m_b²⟩
        want = math.sqrt((mw2[a] * w_true + mb2[a] * (w_filter - w_true)) / w_filter)
        assert c.white_factor[a] == pytest.approx(want, rel=tol)
        # the wander: the extra driving noise (⟨m_b²⟩ − 1)·q of every bias state of the filter, per second
        q = sum((c_.values[0] if c_.kind == "RW" else c_.values[1] * (1 - c_.values[0] ** 2))
                for c_ in pairs[a].components if c_.kind in ("RW", "AR1"))
        assert c.k[a] ** 2 == pytest.approx((mb2[a] - 1.0) * q * f, rel=tol, abs=1e-30)
        assert c.sigma[a] == pytest.approx(c.k[a] * math.sqrt(c.tau_s[a] / 2.0), rel=1e-12)
    assert c.k[0] == 0.0 and c.sigma[0] == 0.0  # gyro x: no bias term in the law
    assert c.k[1] > 0 and c.k[2] > 0


def test_departure_steps_become_a_walk_over_the_moving_time():
    sc = simulate_scenario(7400098, duration_s=240.0, n_stops=1, n_outages=0, motion_noise="gyro_departure_step")
    c = constant_in_motion(sc, true_static_models(sc))
    sched = sc.extra["law_schedule"]
    i0, mv = _moving(sc)
    n_dep = int(np.sum(sched.departure_index > i0))
    assert n_dep >= 2  # the start after the static beginning and after the stop
    t_m = mv.sum() / sc.rate
    for a in range(3):
        assert c.k[a] ** 2 == pytest.approx(n_dep * sched.step_var[a] / t_m, rel=1e-12)
        assert c.tau_s[a] == t_m
        # P0 = σ² = K² T_M / 2: half the step variance the drive adds
        assert c.sigma[a] ** 2 == pytest.approx(n_dep * sched.step_var[a] / 2.0, rel=1e-12)
    assert c.white_factor == pytest.approx((1.0,) * 6, rel=1e-12) and c.sigma[3:] == (0.0,) * 3


@pytest.mark.slow  # two filter runs with a branch per window on a 300 s drive (and the kernels' compilation)
def test_oracle_const_is_oracle_law_under_a_moving_gauss_markov_and_runs_end_to_end():
    sc = simulate_scenario(7400097, duration_s=300.0, n_stops=2, n_outages=0, motion_noise="gyro_moving_gm")
    c = constant_in_motion(sc, true_static_models(sc))
    assert c.sigma[:3] == pytest.approx([float(x) for x in sc.extra["law_schedule"].gm_sigma[:3]], rel=0)
    assert c.tau_s[:3] == (60.0,) * 3 and c.white_factor == pytest.approx((1.0,) * 6, rel=1e-12)
    windows = dense.dense_windows(sc, dense.parse_outages("dense:60:20")[1])
    const = dense.evaluate_method(sc, "oracle_const", sc.gnss, windows, nees=True)
    law = dense.evaluate_method(sc, "oracle_law", sc.gnss, windows)
    assert const["oracle_const"]["sigma"][:3] == list(c.sigma[:3])
    assert len(const["windows"]) == len(windows) >= 8 and const["nees"]["n"] > 100  # the aided run's NEES epochs
    for a, b in zip(const["windows"], law["windows"], strict=True):  # the family holds this law exactly
        assert a["drift"] == pytest.approx(b["drift"], rel=1e-9)
    # oracle_const_gmwm puts the same constant part on in_use's static part: handed the truth's, it is oracle_const
    from types import SimpleNamespace

    on = dense.evaluate_method(sc, "oracle_const_gmwm", sc.gnss, windows, in_use=SimpleNamespace(
        models=true_static_models(sc)))
    assert [w["drift"] for w in on["windows"]] == [w["drift"] for w in const["windows"]]
    with pytest.raises(Exception, match="--vehicle-drives 2 or more"):
        dense.evaluate_method(sc, "oracle_const_gmwm", sc.gnss, windows)
