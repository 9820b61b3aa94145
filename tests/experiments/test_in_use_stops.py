"""The ``in_use_stops`` row: the ``in_use`` model navigated the way ``online --imu-model`` does (the online engine,
its static part refit at the stops, the in-motion part composed with every refit;
:mod:`imunoise.experiments.in_use_method`)."""

from __future__ import annotations

import numpy as np
import pytest

from imunoise.errors import ModelError
from imunoise.experiments import dense
from imunoise.experiments.carry_over import earlier_scenarios, learning_drives
from imunoise.experiments.common import simulate_scenario
from imunoise.experiments.dense_methods import method_setup
from imunoise.experiments.dense_warm import gmwm_on_drives
from imunoise.experiments.gnss_regimes import GnssRegime
from imunoise.experiments.in_use_method import InUseModel, in_use_stops_run, learn_in_use
from imunoise.inuse import InMotionPart
from imunoise.inuse.likelihood import drive_moving

SCEN = {"duration_s": 200.0, "n_stops": 1, "motion_noise": "drive0708"}
SEED = 4802
WINDOWS = [(100030.0, 30.0), (100090.0, 30.0)]


def run_windows_in_use_stops(sc, gnss, windows, model, **kw) -> dict:
    """The row's run (:func:`in_use_stops_run` through :func:`dense.run_windows`, as ``evaluate_method`` runs it)."""
    cfg, rk = in_use_stops_run(sc, model)
    return dense.run_windows(sc, cfg, gnss, windows, **rk, **kw)


@pytest.fixture(scope="module")
def vehicle():
    """(scored drive, its fixes, the in_use model learned on the vehicle's earlier drive)."""
    sc = simulate_scenario(SEED, n_outages=0, **SCEN)
    rg = GnssRegime()
    d = learning_drives(SEED, 2, earlier_scenarios(SEED, 1, **SCEN), rg, 1)
    run = gmwm_on_drives(d)
    return sc, rg.apply(sc.gnss, 1_000_003 * SEED + 1), learn_in_use(d, run.fits, None, run.static_pieces)


@pytest.mark.slow
def test_without_in_motion_terms_it_is_the_gmwm_engine_on_the_pooled_stops(vehicle):
    """A part with no in-motion term (factor 1, no wander): the row is the ``gmwm`` row's engine started from
    ``in_use``'s static part with the learning drives' stops pooled, to the bit. The reference flushes the
    covariance at the same samples (the moving flag's flips, where the schedule sets the filter's noise, which
    propagates P first): without that the two differ by their flush points alone (≈ 1e-5 m here)."""
    sc, gnss, m = vehicle
    null = InUseModel(m.models, InMotionPart({}), 0.0, 0, m.drives, m.static_pieces)
    got = run_windows_in_use_stops(sc, gnss, WINDOWS, null, nees=True)
    cfg, _, upd = method_setup("gmwm", sc, None, {})
    mv = drive_moving(sc)
    flips = np.concatenate([[0], np.flatnonzero(mv[1:] != mv[:-1]) + 1])
    want = dense.run_windows(sc, cfg, gnss, WINDOWS, initial_models=m.models, updater=upd,
                             earlier_static=m.static_pieces, nees=True,
                             prepare=lambda nav: nav.add_event_source(flips, lambda nv, i: nv.ekf.flush()))
    assert got == want
    assert all(np.isfinite(w["drift"]) for w in got["windows"])


@pytest.mark.slow
def test_it_refits_the_static_part_at_the_scored_drives_stops(vehicle):
    sc, gnss, m = vehicle
    assert m.part.white_factors() != [1.0] * 6  # the learned part has in-motion terms
    res = run_windows_in_use_stops(sc, gnss, WINDOWS, m, nees=True, keep=True)
    ev = res["_full"].events
    pooled = [e for e in ev if e["event"] == "earlier_static"]
    assert len(pooled) == 1 and pooled[0]["static_s"] > 60.0  # the learning drive's stops, pooled at the start
    jobs = [e["job"] for e in ev if e["event"] == "swap"]
    assert jobs[0] == "identify" and "refit" in jobs[1:]  # identified on them, refit at this drive's stop
    null = InUseModel(m.models, InMotionPart({}), 0.0, 0, m.drives, m.static_pieces)
    plain = run_windows_in_use_stops(sc, gnss, WINDOWS, null, nees=True)
    assert [w["drift"] for w in res["windows"]] != [w["drift"] for w in plain["windows"]]  # the part is used
    assert res["nees"]["n"] == plain["nees"]["n"] > 0


def test_it_needs_the_stops_the_static_part_was_fitted_on():
    sc = simulate_scenario(4800, n_outages=0, **SCEN)
    m = InUseModel([], InMotionPart({}), 0.0, 0, [])
    with pytest.raises(ModelError, match="in_use_stops pools the stops.*use in_use"):
        run_windows_in_use_stops(sc, sc.gnss, [], m)
    with pytest.raises(ModelError, match="in_use_stops\\+sf: in_use_stops has no scale-factor"):
        dense.evaluate_method(sc, "in_use_stops+sf", sc.gnss, [], in_use=m)
