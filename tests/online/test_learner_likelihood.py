"""The learner's likelihood statistic (``MotionNoiseConfig(statistic="likelihood")``): the likelihood-ratio tests,
the GNSS σ-scale rival, the drift harm guard and the state machine on synthetic rounds (no filter runs here;
the stored per-fix NLL is tested in tests/nav/test_innovation_nll.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2

from imunoise.errors import ModelError
from imunoise.online.learner import LearnedProcess, MotionNoiseConfig, MotionNoiseLearner
from imunoise.online.learner.likelihood import drift_harm, lr_test, lr_threshold


def test_lr_test_uses_the_chi2_quantile_at_the_bonferroni_level():
    assert lr_threshold(0.05, 1) == pytest.approx(3.841, abs=1e-3)
    assert lr_threshold(0.05 / 21, 1) == pytest.approx(chi2.isf(0.05 / 21, 1))
    v = lr_test([10.0, 10.0], [15.0, 14.0], 0.05 / 21, 1)  # ΔNLL = −9 → LR 18 > 9.23
    assert v.ok and v.lr == pytest.approx(18.0) and v.delta_nll == pytest.approx(-9.0) and v.n_rounds == 2
    w = lr_test([10.0, 10.0], [12.0, 12.0], 0.05 / 21, 1)  # LR 8 < 9.23
    assert not w.ok and w.threshold == pytest.approx(9.2299, abs=1e-3)
    assert not lr_test([math.nan], [1.0], 0.05, 1).ok


def test_a_null_candidate_passes_the_lr_test_at_the_stated_rate():
    # under the null, LR of a nested one-parameter alternative is χ²₁: P(LR > threshold) = level
    rng = np.random.default_rng(3)
    lr = rng.chisquare(1, 200_000)
    for level in (0.05, 0.05 / 21):
        rate = np.mean(lr > lr_threshold(level, 1))
        assert abs(rate - level) < 4 * math.sqrt(level / lr.size) + 1e-4


def test_drift_harm_guard_uses_rehearsed_rounds_only():
    harm, mean, n = drift_harm([1.2, math.nan, 1.1], [1.0, 0.5, 1.0], 0.05)
    assert harm and mean == pytest.approx(0.15) and n == 2
    assert drift_harm([0.9, 1.0], [1.0, 1.0], 0.05)[0] is False
    assert drift_harm([math.nan], [1.0], 0.05) == (False, pytest.approx(math.nan, nan_ok=True), 0)


def test_config_statistic_default_and_bad_values():
    assert MotionNoiseConfig().statistic == "drift"
    with pytest.raises(ModelError, match="statistic must be one of drift, likelihood, got 'nll'"):
        MotionNoiseConfig(statistic="nll")
    with pytest.raises(ModelError, match="r_scales"):
        MotionNoiseConfig(statistic="likelihood", r_scales=(1.0,))


# -- the state machine on synthetic rounds ----------------------------------------------------------
def _learner(**kw):
    return MotionNoiseLearner(MotionNoiseConfig(statistic="likelihood", warm_rounds=1, choose_rounds=3,
                                                confirm_rounds=3, **kw), 100.0, np.zeros(3))


def _arm(L, specs, roles, rscale=None):
    L._specs, L._roles = list(specs), list(roles)
    L._rscale = list(rscale) if rscale is not None else [1.0] * len(specs)
    L._shadows = [object() for _ in specs]
    L.n_searches += 1
    L._reset_search()


def _round(L, nll, scores=None, rehearsed=True, nis_mean=3.0, n_fix=20):
    k = len(L._specs)
    nis = np.zeros((k, 4))
    nis[:, 0], nis[:, 1] = np.asarray(nis_mean, dtype=float) * n_fix, n_fix
    sc = np.zeros(k) if scores is None else np.asarray(scores, dtype=float)
    L._decide({"scores": sc if rehearsed else np.full(k, np.nan), "nis": nis, "rehearsed": rehearsed,
               "nll": np.asarray(nll, dtype=float), "cpu_s": 0.01, "t": 100.0 + len(L.round_s)}, None)


GOOD = (LearnedProcess("gm", "gyro", 1e-4, 10.0),)
OTHER = (LearnedProcess("white", "accel", 2.0),)


def test_state_machine_confirms_by_lr_counts_unrehearsed_rounds_and_reverts():
    L = _learner()
    _arm(L, [(), GOOD, OTHER, (), ()], ["current", "candidate", "candidate", "rscale", "rscale"],
         [1.0, 1.0, 1.0, 0.7, 1.4])
    _round(L, [0, 0, 0, 0, 0])  # warm
    for r in range(3):  # a round without rehearsal counts too (the fixes were processed)
        _round(L, [100.0, 95.0, 101.0, 102.0, 99.0], rehearsed=r != 1)
    h = L.history[-1]
    assert h["decision"] == "choose" and h["processes"] == [GOOD[0].to_dict()] and h["delta_nll"] == -15.0
    assert h["r_scale"] == 1.4 and h["r_delta_nll"] == -3.0
    assert [e is not None for e in L._shadows] == [True, True, False, False, True]  # current, chosen, R rival
    for _ in range(3):
        _round(L, [100.0, 96.0, math.nan, math.nan, 99.0], scores=[1.0, 0.9, 0, 0, 1.0])
    h = L.history[-1]
    assert h["decision"] == "confirm" and h["switch"] and L.spec == GOOD and L.previous == ()
    assert h["lr"] == pytest.approx(24.0) and h["threshold"] == pytest.approx(lr_threshold(0.05 / 2, 1))
    assert h["r_lr"] == pytest.approx(18.0) and h["delta_nll"] == pytest.approx(-12.0) and h["n_rounds"] == 3
    assert h["statistic"] == "likelihood" and h["mean_log_ratio"] == pytest.approx(-0.1)
    # the next search: the previous model explains the fixes better → revert at χ²₁(0.95)
    _arm(L, [GOOD, (), OTHER], ["current", "previous", "candidate"])
    _round(L, [0, 0, 0])
    for _ in range(3):
        _round(L, [100.0, 98.0, 100.0])
    h = L.history[-1]
    assert h["decision"] == "revert" and L.spec == () and h["lr"] == pytest.approx(12.0)
    assert h["threshold"] == pytest.approx(lr_threshold(0.05, 1))


@pytest.mark.parametrize("case", ["r_scale", "lr", "harm"])
def test_state_machine_refuses_what_the_rival_the_threshold_or_the_drift_guard_stops(case):
    L = _learner()
    _arm(L, [(), GOOD, ()], ["current", "candidate", "rscale"], [1.0, 1.0, 0.7])
    _round(L, [0, 0, 0])
    for _ in range(3):
        _round(L, [100.0, 95.0, 96.0])
    assert L.history[-1]["decision"] == "choose"
    cand = {"r_scale": [100.0, 95.0, 94.0], "lr": [100.0, 99.5, 100.0], "harm": [100.0, 95.0, 100.0]}[case]
    for _ in range(3):
        _round(L, cand, scores=[1.0, 1.2 if case == "harm" else 1.0, 1.0])
    h = L.history[-1]
    reason = {"r_scale": "a GNSS σ scale explains the fixes as well", "lr": "LR below its threshold",
              "harm": "the rehearsed drift is worse (harm guard)"}[case]
    assert h["decision"] == "refuse" and h["stage"] == "confirm" and h["reason"] == reason and L.spec == ()


def test_state_machine_refuses_at_choose_when_nothing_beats_the_current_model():
    L = _learner()
    _arm(L, [(), GOOD, ()], ["current", "candidate", "rscale"], [1.0, 1.0, 1.4])
    _round(L, [0, 0, 0])
    for _ in range(3):
        _round(L, [100.0, 101.0, 99.0])
    h = L.history[-1]
    assert h["decision"] == "refuse" and h["stage"] == "choose" and h["candidates"]["1"]["delta_nll"] == 3.0


def test_cli_bad_statistic_is_one_line_and_exit_2(tmp_path, capsys):
    from imunoise.cli import main

    rc = main(["online", "--imu", str(tmp_path / "none.txt"), "--learn-motion-noise", "--motion-noise-statistic",
               "nll", "--out", str(tmp_path / "y")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert "--motion-noise-statistic must be one of drift, likelihood, got 'nll'" in err[0]
    assert not (tmp_path / "y").exists()
