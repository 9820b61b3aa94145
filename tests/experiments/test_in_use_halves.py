"""Cross-fitting on the halves of one drive (imunoise.experiments.drive_halves, ``--learn-half``): the scored half's
windows are a subset of the whole drive's with the same values, its NEES epochs partition the drive's, and the
in-motion estimate learns on the other half only."""

from __future__ import annotations

import numpy as np
import pytest

from imunoise.errors import ModelError
from imunoise.experiments import dense
from imunoise.experiments import drive_halves as dh
from imunoise.experiments.common import simulate_scenario
from imunoise.inuse.likelihood import DriveLikelihood, Theta
from imunoise.online import OnlineConfig

SCEN = {"duration_s": 300.0, "n_stops": 2, "motion_noise": "drive0708"}
SPEC = dense.DenseSpec(30.0, 10.0, 60.0)
BASE = OnlineConfig(latency=0.5)  # models take effect at fixed times: a rerun is bit-identical


def _same_windows(got: list[dict], want: list[dict], *, rel: float = 0.0) -> None:
    assert len(got) == len(want) and [sorted(g) for g in got] == [sorted(w) for w in want]
    if rel == 0.0:
        assert got == want  # identical, not close
    else:
        for g, w in zip(got, want, strict=True):
            assert g == pytest.approx(w, rel=rel, abs=0.0)


@pytest.fixture(scope="module")
def drive():
    return simulate_scenario(4810, n_outages=0, **SCEN)


def test_halves_are_cut_midway_and_a_span_keeps_only_its_windows(drive):
    sp = dh.half_spans(drive)
    t_last = float(np.max(drive.gnss.t))
    assert sp["first"] == (float(drive.init.t), pytest.approx(0.5 * (drive.init.t + t_last)))
    assert sp["first"][1] == sp["second"][0] and sp["second"][1] == t_last + 1.0
    w = dense.dense_windows(drive, SPEC)
    a, b = dh.windows_in(w, sp["first"]), dh.windows_in(w, sp["second"])
    assert a and b and set(a) | set(b) <= set(w) and not set(a) & set(b)
    assert a == [x for x in w if x in a] and b == [x for x in w if x in b]  # the drive's order kept
    assert all(s + L <= sp["first"][1] for s, L in a) and all(s >= sp["second"][0] for s, _ in b)
    straddle = [x for x in w if x[0] < sp["first"][1] < x[0] + x[1]]
    assert straddle and not set(straddle) & (set(a) | set(b))  # an outage across the cut is scored in neither half
    assert dh.other_half("first") == "second" and dh.other_half("second") == "first"
    with pytest.raises(ModelError, match="--learn-half must be 'first' or 'second'"):
        dh.check_half("middle")


# oracle_law is not here: its noise schedule is averaged over pieces cut at the window starts, so its values
# depend on which windows are run (1e-5 relative measured); the real drive has no oracle
@pytest.mark.parametrize("name", ["plain", pytest.param("static_var", marks=pytest.mark.slow), "gmwm"])
def test_scored_half_windows_keep_their_values_and_its_nees_epochs_partition_the_drive(drive, name):
    w = dense.dense_windows(drive, SPEC)
    drive.extra.pop("job_cache", None)
    whole = dense.evaluate_method(drive, name, drive.gnss, w, base=BASE, cache={}, nees=True)
    nees = []
    for learn in ("second", "first"):
        sc = dh.scored_half(drive, learn)
        sub = dh.windows_in(w, dh.half_spans(drive)[dh.other_half(learn)])
        sc.extra.pop("job_cache", None)
        got = dense.evaluate_method(sc, name, sc.gnss, sub, base=BASE, cache={}, nees=True)
        _same_windows(got["windows"], [whole["windows"][w.index(x)] for x in sub])
        nees.append(got["nees"])
    assert nees[0]["n"] > 0 and nees[1]["n"] > 0
    assert nees[0]["n"] + nees[1]["n"] == whole["nees"]["n"]
    assert nees[0]["inside"] + nees[1]["inside"] == whole["nees"]["inside"]
    assert nees[0]["sum"] + nees[1]["sum"] == pytest.approx(whole["nees"]["sum"], rel=1e-12)


def test_the_learning_half_scores_only_its_own_fixes(drive):
    sp = dh.half_spans(drive)
    first, second = dh.learning_half(drive, drive.gnss, "first"), dh.learning_half(drive, drive.gnss, "second")
    assert float(first.imu.t[-1]) <= sp["first"][1] and float(np.max(first.gnss.t)) <= sp["first"][1]
    assert first.static_truth.size == first.imu.t.size and first.extra["score_after_s"] == sp["first"][0]
    assert second.imu.t.size == drive.imu.t.size and second.extra["score_after_s"] == sp["second"][0]
    # moving the second half's fixes by 50 m changes nothing of what the first half's estimate sees
    g = drive.gnss
    llh = np.asarray(g.llh, dtype=float).copy()
    llh[np.asarray(g.t) >= sp["second"][0], 0] += 50.0 / 6.4e6
    moved = type(g)(t=g.t, llh=llh, sigma_ned=g.sigma_ned)
    models = dense.method_setup("gmwm_hindsight", drive, BASE, {})[1]
    nll = [DriveLikelihood([dh.learning_half(drive, x, "first")], models).nll(Theta()) for x in (g, moved)]
    assert np.isfinite(nll[0]) and nll[0] == nll[1]
    # ... and the second half's estimate scores only its own fixes: the same moved fixes change its likelihood
    nll2 = [DriveLikelihood([dh.learning_half(drive, x, "second")], models).nll(Theta()) for x in (g, moved)]
    assert nll2[1] > nll2[0] + 100.0


@pytest.mark.slow
def test_in_use_learned_on_one_half_navigates_the_other(drive):
    """The ``in_use`` model of half "first": the static part is ``gmwm_hindsight``'s (the same six filter models),
    the in-motion part names the half; its windows in the second half are the unrestricted run's values."""
    cache: dict = {}
    model = dh.learn_on_half(drive, drive.gnss, "first", BASE, cache)
    ref = dense.method_setup("gmwm_hindsight", drive, BASE, cache)[1]
    assert [(m.to_dict(), m.freq) for m in model.models] == [(m.to_dict(), m.freq) for m in ref]
    assert model.drives == [f"{drive.name} (first half)"] and model.runs > 0
    w = dense.dense_windows(drive, SPEC)
    sub = dh.windows_in(w, dh.half_spans(drive)["second"])
    whole = dense.evaluate_method(drive, "in_use", drive.gnss, w, base=BASE, in_use=model)
    got = dense.evaluate_method(dh.scored_half(drive, "first"), "in_use", drive.gnss, sub, base=BASE, in_use=model)
    # the batch filter flushes its accumulated covariance propagation at every piece end, and its pieces are cut
    # at the window starts: another set of windows groups the same arithmetic otherwise (measured: 2.3e-7
    # relative on the end drift of this drive's windows); the online rows above agree to the bit
    _same_windows(got["windows"], [whole["windows"][w.index(x)] for x in sub], rel=1e-5)


def test_cli_refuses_learn_half_on_the_simulator(tmp_path, capsys):
    from imunoise.cli import main

    assert main(["experiment", "online", "--sim", "--outages", "dense:30:30:60", "--learn-half", "first",
                 "--out", str(tmp_path / "a")]) == 2
    assert "--learn-half cross-fits on the halves of a real drive" in capsys.readouterr().err


def test_cli_refuses_in_use_stops_with_learn_half_before_any_work(tmp_path, capsys):
    """in_use_stops pools the stops its static part was learned on; --learn-half fits that part on the whole drive's
    stops, so the pair is refused at the arguments (exit 2, one line), not after the half's learning runs."""
    from imunoise.cli import main

    out = tmp_path / "a"
    assert main(["experiment", "online", "--data", str(tmp_path / "absent"), "--outages", "dense:60:60:60",
                 "--methods", "gmwm,in_use_stops", "--learn-half", "first", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--methods in_use_stops" in err and "use in_use with --learn-half" in err and len(err.splitlines()) == 1
    assert not out.exists()


@pytest.mark.slow
def test_run_real_with_learn_half_scores_the_other_half_only():
    from conftest import REPO

    data = REPO / "data" / "drive_0708"
    if not (data / "dataset.json").exists():
        pytest.skip(f"the shipped drive is absent: {data.relative_to(REPO)}")
    kw = {"spec": dense.DenseSpec(60.0, 60.0, 60.0), "workers": 1, "n_boot": 200, "base": BASE}
    with pytest.raises(ModelError, match="drop --learn-from-logs"):
        dense.run_real(data, methods=("plain", "in_use"), learn_half="first", learn_from=[data], **kw)
    whole = dense.run_real(data, methods=("plain",), paper_windows=False, **kw)
    res = dense.run_real(data, methods=("plain", "in_use"), learn_half="first", **kw)
    mid = res["halves"]["spans_s"]["second"][0]
    (name,) = res["windows"]
    got = res["windows"][name]
    assert got and all(s >= mid for s, _ in got)
    allw = whole["windows"][name]
    for met in ("drift", "rms", "aided_rms"):
        vals = whole["per_window"]["rtk"][met]["plain"][0][0]
        assert res["per_window"]["rtk"][met]["plain"][0][0] == [vals[allw.index(x)] for x in got]
    assert 0 < res["nees"]["rtk"]["plain"]["epochs"] < whole["nees"]["rtk"]["plain"]["epochs"]
    assert res["in_use_models"][f"{name}/rtk/0"]["drives"] == [f"{name} (first half)"]
