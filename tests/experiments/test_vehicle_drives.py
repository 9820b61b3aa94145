"""Vehicles of several drives (imunoise.experiments.carry_over, ``--vehicle-drives K``) and the NEES of the
dense-window evidence (imunoise.experiments.nees)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.stats import chi2

from imunoise.errors import ModelError
from imunoise.experiments import dense
from imunoise.experiments.carry_over import (
    check_vehicle_drives,
    earlier_scenarios,
    learning_drives,
    vehicle_seeds,
)
from imunoise.experiments.common import simulate_scenario
from imunoise.experiments.gnss_regimes import parse_gnss
from imunoise.experiments.nees import BAND6, drive_nees, nees_summary
from imunoise.online import OnlineConfig

SCEN = {"duration_s": 200.0, "n_stops": 1, "motion_noise": "drive0708"}
SPEC = dense.DenseSpec(30.0, 30.0, 60.0)


def test_the_drives_of_a_vehicle_share_the_imu_and_law_not_the_route():
    seeds = vehicle_seeds(4800, 3)
    assert seeds[-1] == 4800 and len(set(seeds)) == 3  # scored on the last: the seed's own drive
    last = simulate_scenario(4800, n_outages=0, **SCEN)
    earlier = earlier_scenarios(4800, 2, **SCEN)
    drives = [*earlier[::-1], last]  # oldest first, as vehicle_seeds
    assert [d.extra["seed"] for d in drives] == seeds
    for d in drives[:-1]:
        assert d.extra["static_models"] == last.extra["static_models"]  # the IMU's noise models
        assert d.extra["motion_noise"] == last.extra["motion_noise"]  # its motion law
        assert np.array_equal(d.lever, last.lever)  # the vehicle
        assert d.extra["stops"] != last.extra["stops"]  # other stops ...
        n = min(d.ref.llh.shape[0], last.ref.llh.shape[0])
        assert np.max(np.abs(d.ref.llh[:n, :2] - last.ref.llh[:n, :2])) > 1e-6  # ... and another route
        m = min(d.imu.t.size, last.imu.t.size)
        assert not np.array_equal(d.imu.dtheta[:m], last.imu.dtheta[:m])  # other noise draws
    rg = parse_gnss("noise:1.5,3,1")
    learn = learning_drives(4800, 3, earlier, rg, 1)
    assert [sc.extra["seed"] for sc, _ in learn] == seeds[:-1]
    sc0, g0 = learn[0]  # the GNSS noise seeded like the drive's own in the evidence
    np.testing.assert_array_equal(g0.llh, rg.apply(sc0.gnss, 1_000_003 * seeds[0] + 1).llh)


@pytest.mark.parametrize("bad", [0, -1, "0", "-2", "two", "1.5", None])
def test_bad_vehicle_drives_is_one_line(bad):
    with pytest.raises(ModelError, match="--vehicle-drives must be a whole number of drives >= 1"):
        check_vehicle_drives(bad)


@pytest.mark.parametrize("k, extra, says", [
    ("0", ["--sim", "--outages", "dense:30:30:60"], "--vehicle-drives must be a whole number"),
    ("-3", ["--sim", "--outages", "dense:30:30:60"], "--vehicle-drives must be a whole number"),
    ("2", ["--sim"], "add --sim and --outages dense:L:S"),
])
def test_cli_refuses_bad_vehicle_drives_in_one_line(tmp_path, capsys, k, extra, says):
    from imunoise.cli import main

    out = tmp_path / "never"
    assert main(["experiment", "online", *extra, "--vehicle-drives", k, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert says in err and err.count("\n") == 0 and not out.exists()


def test_scored_on_the_last_drive_and_one_drive_is_todays_run():
    """K = 2 adds an earlier drive no method here learns from: every value equals K = 1's, which is the run
    without the option (the same scored drive, the same windows, the same filters)."""
    kw = {"spec": SPEC, "methods": ("plain", "oracle_law"), "workers": 1, "n_boot": 200, **SCEN}
    one = dense.run_sim([4800], **kw)
    two = dense.run_sim([4800], vehicle_drives=2, **kw)
    assert one["per_window"] == two["per_window"]
    assert one["paired"] == two["paired"] and one["nees"] == two["nees"]
    assert two["vehicles"] == {"4800": [4800 + dense.PRIOR_SEED_OFFSET, 4800]} and one["vehicles"]["4800"] == [4800]
    assert one["windows"] == two["windows"] and list(one["windows"]) == ["simulated drive (seed 4800)"]
    n = one["nees"]["rtk"]
    assert n["oracle_law"]["epochs"] == n["plain"]["epochs"] == 140  # 1 Hz epochs from 60 s to the end
    assert n["oracle_law"]["share_inside"] > n["plain"]["share_inside"]  # the true law's filter is consistent


@pytest.mark.slow  # eight evaluate_method runs: minutes
def test_the_nees_leaves_every_window_value_as_it_was():
    """The NEES reads the aided run's state at its 1 Hz epochs (the chunk path split there, the per-sample path
    as it runs, the law's batch filter with its covariance kept): the windows are the same to the bit."""
    sc = simulate_scenario(4801, n_outages=0, **SCEN)
    w = dense.dense_windows(sc, SPEC)
    base = OnlineConfig(latency=0.5)  # the models take effect at fixed times: a rerun is bit-identical
    for m in ("plain", "static_var", "oracle_law", "gmwm"):
        sc.extra.pop("job_cache", None)
        a = dense.evaluate_method(sc, m, sc.gnss, w, base=base, cache={})
        sc.extra.pop("job_cache", None)
        b = dense.evaluate_method(sc, m, sc.gnss, w, base=base, cache={}, nees=True)
        assert b.pop("nees")["n"] == 140 and a == b, m


def test_nees_summary_pools_epochs_and_bootstraps_drives():
    assert BAND6 == pytest.approx(tuple(chi2.ppf([0.025, 0.975], 6)), rel=1e-12)
    d1 = drive_nees([0.5, 2.0, 6.0, 20.0])  # inside: 2, 6
    assert d1 == {"n": 4, "inside": 2, "sum": 28.5}
    d2 = drive_nees([3.0] * 6)
    s = nees_summary([d1, d2, None], n_boot=500, seed=1)
    assert s["share_inside"] == pytest.approx(8 / 10) and s["mean_nees"] == pytest.approx(46.5 / 10)
    assert s["drives"] == 2 and s["epochs"] == 10
    assert 0.5 <= s["ci95"][0] <= 0.8 <= s["ci95"][1] <= 1.0  # the bootstrap's range: drives resampled whole
    assert nees_summary([None])["share_inside"] is None


def test_cli_vehicle_drives_writes_the_nees_table(tmp_path, capsys):
    from imunoise.cli import main

    out = tmp_path / "ev"
    assert main(["experiment", "online", "--sim", "--seeds", "2", "--seed0", "4800", "--duration", "200", "--stops",
                 "1", "--outages", "dense:30:30:60", "--methods", "plain,oracle_law", "--vehicle-drives", "2",
                 "--workers", "1", "--bootstrap", "200", "--out", str(out)]) == 0
    res = json.loads((out / "results.json").read_text())
    assert res["vehicle_drives"] == 2 and set(res["vehicles"]) == {"4800", "4801"}
    assert "NEES pos+vel (6 dof) inside its 95 % band, rtk, oracle_law" in capsys.readouterr().out
    assert "Consistency: NEES of position + velocity" in (out / "report.md").read_text()
    assert (out / "nees.csv").exists()


@pytest.mark.slow
def test_in_use_learns_on_the_earlier_drive_and_navigates_the_last():
    """``in_use`` on vehicles of two drives: its model comes from the earlier drive alone (the drive of seed +
    PRIOR_SEED_OFFSET), with the in-motion part the model file carries; the scored drive and every other row are
    those of the run without it."""
    kw = {"spec": SPEC, "workers": 1, "n_boot": 200, "vehicle_drives": 2, **SCEN}
    res = dense.run_sim([4802], methods=("plain", "in_use", "oracle_law"), **kw)
    ref = dense.run_sim([4802], methods=("plain", "oracle_law"), **kw)
    for met in ("drift", "rms", "aided_rms"):
        for m in ("plain", "oracle_law"):
            assert res["per_window"]["rtk"][met][m] == ref["per_window"]["rtk"][met][m]
        vals = [v for d in res["per_window"]["rtk"][met]["in_use"] for r in d for v in r]
        assert vals and all(v is not None and np.isfinite(v) for v in vals)
    assert res["nees"]["rtk"]["in_use"]["epochs"] == 140
    assert list(res["in_use_models"]) == ["4802/rtk/0"] and "in_motion" in res["in_use_models"]["4802/rtk/0"]
    job = dense._sim_job((4802, ("in_use",), (parse_gnss("rtk"),), (1,), SPEC, dict(SCEN), None, 2))
    learned = job["runs"][0][3]["in_use"]
    assert learned["drives"] == [f"simulated drive (seed {4802 + dense.PRIOR_SEED_OFFSET})"]
    axes = learned["in_motion"]["axes"]
    assert set(axes) == {"gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"}
    assert learned["in_motion"]["evidence"]["hours_moving"] > 0 and learned["filter_runs"] > 0


def test_in_use_needs_earlier_drives(tmp_path, capsys):
    from imunoise.cli import main

    with pytest.raises(ModelError, match="vehicle_drives must be 2 or more"):
        dense.run_sim([4800], spec=SPEC, methods=("in_use",), workers=1, **SCEN)
    assert main(["experiment", "online", "--sim", "--outages", "dense:30:30:60", "--methods", "plain,in_use",
                 "--out", str(tmp_path / "a")]) == 2
    assert "give --vehicle-drives 2 or more" in capsys.readouterr().err
    assert main(["experiment", "online", "--sim", "--outages", "dense:30:30:60", "--learn-from-logs", "x",
                 "--out", str(tmp_path / "b")]) == 2
    assert "on the simulator use --vehicle-drives K" in capsys.readouterr().err


@pytest.mark.slow
def test_learn_from_logs_gives_in_use_its_drives_on_real_data():
    """On real data ``in_use`` learns on the dataset folders of ``learn_from`` (here the shipped drive itself: the
    plumbing, not a carry-over claim) and navigates the drive of ``data_dir``; without them it is refused."""
    from conftest import REPO

    data = REPO / "data" / "drive_0708"
    if not (data / "dataset.json").exists():
        pytest.skip(f"the shipped drive is absent: {data.relative_to(REPO)}")
    kw = {"spec": dense.DenseSpec(60.0, 120.0, 60.0), "workers": 1, "n_boot": 200, "paper_windows": False}
    with pytest.raises(ModelError, match="--learn-from-logs DATASET"):
        dense.run_real(data, methods=("in_use",), **kw)
    res = dense.run_real(data, methods=("plain", "in_use"), learn_from=[data], **kw)
    assert res["learn_from_logs"] == [str(data)]
    vals = [v for d in res["per_window"]["rtk"]["drift"]["in_use"] for r in d for v in r]
    assert vals and all(np.isfinite(v) for v in vals)
    assert res["nees"]["rtk"]["in_use"]["epochs"] > 300 and res["nees"]["rtk"]["plain"]["epochs"] > 300


def test_in_use_has_no_filter_variants():
    sc = simulate_scenario(4800, n_outages=0, **SCEN)
    with pytest.raises(ModelError, match="in_use\\+sf: in_use has no scale-factor or NHC variant"):
        dense.evaluate_method(sc, "in_use+sf", sc.gnss, [], in_use=object())
    with pytest.raises(ModelError, match="--vehicle-drives 2 or more"):
        dense.evaluate_method(sc, "in_use", sc.gnss, [])


# ---- vehicles on a replayed recording (--imu-noise with --vehicle-drives K)
REPLAY_SCEN = {"duration_s": 200.0, "n_stops": 1, "motion_noise": "none"}


def _replay_file(tmp_path, n=70_000):
    """A synthetic static recording (deg/s and g, 100 Hz): three stretches of a 200 s drive (20 001 samples)."""
    rng = np.random.default_rng(3)
    data = rng.normal(0.0, 0.1, (n, 6)) + np.array([0.5, -0.2, 0.1, 0.01, -0.02, -1.0])
    path = tmp_path / "unit.npz"
    np.savez(path, data=data, columns=np.array(["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]),
             units=np.array(["deg/s"] * 3 + ["g"] * 3), freq_hz=np.float64(100.0))
    return str(path)


def test_replayed_vehicle_drives_take_their_own_stretches_and_score_the_last(tmp_path):
    """Vehicle 4800 of two drives on a replayed recording: its earlier drive replays stretch 0 and its scored drive
    stretch 1 of the same unit, and every value of the scored drive equals the single-drive run whose drive
    replays that stretch (the same seed, the first seed moved by one): the earlier drive changes nothing a
    method that does not learn from it sees."""
    from imunoise.experiments.common import imu_noise_kwargs

    path = _replay_file(tmp_path)
    kw2 = {**REPLAY_SCEN, **imu_noise_kwargs(path, 4800, vehicle_drives=2)}
    n = 20_001
    last = simulate_scenario(4800, n_outages=0, **kw2)
    (earlier,) = earlier_scenarios(4800, 1, **kw2)
    assert earlier.extra["seed"] == 4800 + dense.PRIOR_SEED_OFFSET
    assert last.imu.t.size == earlier.imu.t.size == n
    kw = {"spec": SPEC, "methods": ("plain", "static_var"), "workers": 1, "n_boot": 200,
          "base": OnlineConfig(latency=0.5)}
    two = dense.run_sim([4800], vehicle_drives=2, **kw, **kw2)
    one = dense.run_sim([4800], **kw, **REPLAY_SCEN, **imu_noise_kwargs(path, 4799))  # drive index 1: stretch 1
    assert two["per_window"] == one["per_window"] and two["nees"] == one["nees"]
    assert two["scenario"]["imu_noise_drives"] == 2 and "imu_noise_drives" not in one["scenario"]
    from imunoise.experiments.report import replay_text

    assert "vehicle d = seed − 4800 has 2 drives" in replay_text(two["scenario"])
    assert "drive d = seed − 4799 uses samples [d·n, (d + 1)·n)" in replay_text(one["scenario"])


def test_replayed_vehicles_that_do_not_fit_are_refused_in_one_line(tmp_path, capsys):
    from conftest import one_line_error
    from imunoise.cli import main

    path = _replay_file(tmp_path)  # three stretches of 200 s: one vehicle of two drives, not two
    base = ["experiment", "online", "--sim", "--imu-noise", path, "--duration", "200", "--stops", "1", "--outages",
            "dense:30:30:60", "--methods", "plain", "--vehicle-drives", "2", "--workers", "1", "--seed0", "4800"]
    code = main([*base, "--seeds", "2", "--out", str(tmp_path / "a")])
    one_line_error(code, capsys.readouterr().err, "--vehicle-drives 2", "--seeds ≤ 1", "--duration", path)
    assert not (tmp_path / "a").exists()
    assert main([*base, "--seeds", "1", "--bootstrap", "200", "--out", str(tmp_path / "b")]) == 0  # one fits
    res = json.loads((tmp_path / "b" / "results.json").read_text())
    assert res["vehicle_drives"] == 2 and res["scenario"]["imu_noise_drives"] == 2
    assert res["vehicles"] == {"4800": [4800 + dense.PRIOR_SEED_OFFSET, 4800]}
    from imunoise.experiments.common import imu_noise_kwargs

    with pytest.raises(ModelError, match="--methods gmwm_dyn_warm3 learns on 3 earlier drive.*--vehicle-drives 4"):
        dense.run_sim([4800], spec=SPEC, methods=("plain", "gmwm_dyn_warm3"), workers=1, vehicle_drives=2,
                      **REPLAY_SCEN, **imu_noise_kwargs(path, 4800, vehicle_drives=2))
    with pytest.raises(ModelError, match="imu_noise_kwargs"):  # the layout and the vehicles must agree
        dense.run_sim([4800], spec=SPEC, methods=("plain",), workers=1, vehicle_drives=2, **REPLAY_SCEN,
                      **imu_noise_kwargs(path, 4800))
