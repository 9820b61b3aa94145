"""The in-motion noise learner's decision rule, NIS guard, candidates and state machine on synthetic scores
(imunoise.online.learner; no filter runs here)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imunoise.errors import ModelError
from imunoise.nav.defaults import default_axis_models
from imunoise.noise.processes import AR1, WN
from imunoise.online.learner import LearnedProcess, MotionNoiseConfig, MotionNoiseLearner, MotionNoisePrior
from imunoise.online.learner import decision as dec
from imunoise.online.learner.candidates import (
    DEFAULT_FAMILIES,
    DPH,
    compose,
    departure_variance,
    refine,
    search_candidates,
)


def test_a_truly_better_candidate_is_confirmed():
    rng = np.random.default_rng(1)
    d = -0.2 + 0.05 * rng.standard_normal(5)  # 18 % less drift on each of 5 later rounds
    v = dec.confirm(d, m=21, alpha=0.05, margin=0.01, min_rounds=5)
    assert v.ok and v.level == pytest.approx(0.05 / 21) and v.p < v.level and v.mean < -0.01
    ev = v.evidence()
    assert set(ev) == {"mean_log_ratio", "t_stat", "p", "level", "n_rounds"}


def test_a_null_candidate_among_many_is_confirmed_at_most_at_the_stated_rate():
    # 21 candidates no better than the current model, scores with a common round effect: choose the best mean on
    # 5 rounds, confirm it on 5 later rounds at α/m. Family-wise rate ≤ α; choosing and testing on the same
    # rounds at α without the correction would switch far more often
    rng = np.random.default_rng(7)
    m, reps, alpha = 21, 2000, 0.05
    switched = naive = 0
    for _ in range(reps):
        s = rng.standard_normal((10, m + 1)) * 0.1 + rng.standard_normal((10, 1)) * 0.3
        d = s[:, 1:] - s[:, [0]]
        k = dec.choose(d[:5], [True] * m)
        if k is None:
            continue
        switched += dec.confirm(d[5:, k], m, alpha, 0.0, 5).ok
        naive += dec.paired_test(d[:5, k])[2] < alpha
    assert switched / reps < alpha / 4  # ≈ α/m in expectation
    assert naive / reps > 0.2  # 5.5 × the stated level


def test_confirm_refuses_too_few_rounds_a_small_gain_and_a_weak_p():
    assert "rounds" in dec.confirm([-0.5, -0.5], 1, 0.05, 0.0, 3).reason
    assert "not below" in dec.confirm([-0.005] * 5, 1, 0.05, 0.01, 3).reason
    assert "α/m" in dec.confirm([-0.3, 0.2, -0.4, 0.1, -0.2], 21, 0.05, 0.0, 3).reason


def test_revert_when_later_rounds_contradict_the_switch():
    assert dec.revert([-0.2, -0.25, -0.15, -0.22, -0.18], 0.05, 5).ok  # the previous model drifts less
    assert not dec.revert([0.1, -0.05, 0.12, 0.02, 0.08], 0.05, 5).ok
    assert not dec.revert([-0.2, -0.2], 0.05, 5).ok  # too few rounds


def test_nis_guard_needs_position_and_velocity_inside_their_bands():
    lo, hi = dec.nis_band(100, 3, 0.01)
    assert lo < 3.0 < hi and hi - lo < 1.5
    ok, info = dec.nis_ok([300.0, 0.0], [100, 0])  # position consistent, no velocity aiding
    assert ok and info[1] == {"n": 0}
    assert not dec.nis_ok([300.0, 600.0], [100, 100])[0]  # velocity NIS 6: outside
    assert not dec.nis_ok([120.0, 300.0], [100, 100])[0]  # position NIS 1.2: an underconfident shadow
    assert dec.nis_ok([300.0, 310.0], [100, 100])[0]


def test_candidates_cover_every_family_and_nothing_added_after_a_switch():
    c0 = search_candidates((), DEFAULT_FAMILIES)
    fams = {p.family for s in c0 for p in s}
    assert fams == {(k, s) for k in ("gm", "white", "step") for s in ("gyro", "accel")}
    assert all(len(s) == 1 for s in c0) and () not in c0 and len(c0) == 21
    cur = (LearnedProcess("gm", "gyro", 100 * DPH, 10.0),)
    c1 = search_candidates(cur, DEFAULT_FAMILIES)
    assert c1[0] == () and cur not in c1
    # refined: centred on the best, the ratio its square root, T_c fixed once chosen
    f = refine(DEFAULT_FAMILIES, {("gm", "gyro"): LearnedProcess("gm", "gyro", 300 * DPH, 100.0)})
    assert f[0].centre == pytest.approx(300 * DPH) and f[0].ratio == pytest.approx(math.sqrt(3))
    assert f[0].tc_s == (100.0,)
    assert f[1].centre == DEFAULT_FAMILIES[1].centre


def test_compose_adds_gauss_markov_white_and_the_departure_variance():
    base = default_axis_models(100.0)
    spec = (LearnedProcess("gm", "accel", 0.01, 100.0), LearnedProcess("white", "gyro", 2.0),
            LearnedProcess("step", "gyro", 1e-4))
    out = compose(base, spec, 100.0)
    for a in range(3):
        assert out[a].white_variance() == pytest.approx(4.0 * base[a].white_variance())
        assert sum(isinstance(c, AR1) for c in out[a].components) == sum(
            isinstance(c, AR1) for c in base[a].components)
    for a in range(3, 6):
        ar = [c for c in out[a].components if isinstance(c, AR1)][-1]
        phi, s2 = ar.values
        assert phi == pytest.approx(math.exp(-1 / (100.0 * 100.0)))
        assert s2 / (1 - phi ** 2) == pytest.approx(0.01 ** 2)
        assert sum(isinstance(c, WN) for c in out[a].components) <= 1
    assert departure_variance(spec) == [1e-8] * 3 + [0.0] * 3 and departure_variance(spec[:2]) is None


def test_prior_round_trips_and_bad_settings_are_refused():
    pr = MotionNoisePrior((LearnedProcess("gm", "gyro", 1e-4, 10.0),), DEFAULT_FAMILIES, 12)
    assert MotionNoisePrior.from_dict({"motion_noise": {"evidence": pr.to_dict()}}) == pr
    with pytest.raises(ModelError, match="not a motion-noise prior"):
        MotionNoisePrior.from_dict({"horizontal_rms_m": 1.0})
    with pytest.raises(ModelError, match="overlap"):
        MotionNoiseConfig(outage_s=30.0, every_s=10.0)
    with pytest.raises(ModelError, match="kind"):
        LearnedProcess("ramp", "gyro", 1.0)


# -- the state machine on synthetic rounds ----------------------------------------------------------
def _learner():
    return MotionNoiseLearner(MotionNoiseConfig(warm_rounds=1, choose_rounds=4, confirm_rounds=4), 100.0,
                              np.zeros(3))


def _arm(L, specs, roles):
    L._specs, L._roles = list(specs), list(roles)
    L._shadows = [object() for _ in specs]
    L.n_searches += 1
    L._reset_search()


def _round(L, scores, nis_mean=3.0, n_fix=30):
    nis = np.zeros((len(L._specs), 4))
    nis[:, 0], nis[:, 1] = np.asarray(nis_mean, dtype=float) * n_fix, n_fix
    L._decide({"scores": np.asarray(scores, dtype=float), "nis": nis, "rehearsed": True, "cpu_s": 0.01,
               "t": 100.0 + len(L.round_s)}, None)


def test_state_machine_switches_on_confirmed_evidence_then_reverts_and_logs_every_decision():
    L = _learner()
    good, other = (LearnedProcess("gm", "gyro", 1e-4, 10.0),), (LearnedProcess("white", "accel", 2.0),)
    _arm(L, [(), good, other], ["current", "candidate", "candidate"])
    _round(L, [1.0, 0.0, 0.0])  # warm-up: not scored
    for r in range(4):
        _round(L, [1.0 + 0.01 * r, 0.8, 1.0])
    assert L.history[-1]["decision"] == "choose" and L.history[-1]["processes"] == [good[0].to_dict()]
    assert L._shadows[2] is None  # only the current model and the chosen candidate run to confirm
    for r in range(4):
        _round(L, [1.0 + 0.02 * (r % 2), 0.8, math.nan])
    h = L.history[-1]
    assert h["decision"] == "confirm" and h["switch"] and L.spec == good and L.previous == ()
    assert h["p"] < h["level"] == pytest.approx(0.05 / 2) and h["nis_position"]["inside"]
    # the next search: the previous model (nothing) drifts less on its choose rounds → revert
    _arm(L, [good, (), other], ["current", "previous", "candidate"])
    _round(L, [1.0, 1.0, 1.0])
    for r in range(4):
        _round(L, [1.0, 0.7 + 0.01 * r, 1.1])
    h = L.history[-1]
    assert h["decision"] == "revert" and h["switch"] and L.spec == () and L.previous is None
    assert [x["decision"] for x in L.history] == ["choose", "confirm", "revert"]


def test_state_machine_refuses_a_candidate_outside_its_nis_band():
    L = _learner()
    big = (LearnedProcess("gm", "gyro", 3e-3, 10.0),)
    _arm(L, [(), big], ["current", "candidate"])
    _round(L, [1.0, 1.0])
    for _ in range(4):  # drifts less, but its shadow is underconfident (NIS 1.0 against GNSS)
        _round(L, [1.0, 0.5], nis_mean=[3.0, 1.0])
    assert L.history[-1]["decision"] == "refuse" and L.history[-1]["stage"] == "choose"
    assert not L.history[-1]["candidates"]["1"]["nis_inside"] and L.spec == ()


def test_the_old_name_of_the_learned_process_still_works_with_a_deprecation_warning():
    import imunoise.online.learner as learner
    from imunoise.online.learner import candidates

    for mod in (learner, candidates):
        with pytest.warns(DeprecationWarning, match="LearnedProcess"):
            old = mod.Process
        assert old is LearnedProcess
    import imunoise.noise.processes

    assert imunoise.noise.processes.Process is not LearnedProcess  # the noise process keeps its name
