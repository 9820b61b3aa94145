"""Wheel odometry end to end (imunoise.nav.measurements.odometer, imunoise.io.odometer): the simulator's speed file,
its reader (text and bag topic), bad inputs refused in one line (exit 2), and the odometer keeping the drift of a
seeded simulated drive down through its GNSS outages, alone and with the non-holonomic constraints."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import one_line_error
from imunoise.cli import main
from imunoise.errors import DataError
from imunoise.experiments.common import simulate_scenario
from imunoise.io.odometer import read_odometer
from imunoise.nav.ekf import run_ekf
from imunoise.nav.measurements.nhc import NhcConfig
from imunoise.nav.metrics import nav_errors


@pytest.fixture(scope="module")
def sim(tmp_path_factory) -> dict:
    root = tmp_path_factory.mktemp("odo")
    code = main(["simulate", "--duration", "150", "--stops", "1", "--static-start", "35", "--seed", "4401",
                 "--out", str(root / "drive")])
    assert code == 0
    d = root / "drive"
    t, v, s = np.loadtxt(d / "odometer.txt", unpack=True)

    def write(name, tt=t, vv=v):
        p = root / name
        np.savetxt(p, np.column_stack([tt, vv]), fmt="%.6f", header="t speed")
        return p

    neg, nan = v.copy(), v.copy()
    neg[300] = -1.0
    nan[100:105] = np.nan
    back = t.copy()
    back[[200, 201]] = back[[201, 200]]
    files = {"good": write("speed.txt"), "kmh": write("speed_kmh.txt", vv=v * 3.6), "neg": write("neg.txt", vv=neg),
             "nan": write("nan.txt", vv=nan), "back": write("back.txt", tt=back),
             "unix": write("unix.txt", tt=t + 1.7e9)}
    return {"dir": d, "t": t, "v": v, "s": s, **files}


def _run(argv) -> tuple[int, str]:
    import contextlib
    import io

    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:
            code = int(exc.code or 0)
    return code, err.getvalue()


def test_simulate_writes_the_speed_and_names_it_in_the_manifest(sim):
    d = sim["dir"]
    assert json.loads((d / "dataset.json").read_text())["odometer"] == "odometer.txt"
    assert "ε" in (d / "odometer.txt").read_text().splitlines()[0]  # the drive's scale-factor error, recorded
    ref = np.loadtxt(d / "ref_imu.nav")
    assert np.all(sim["v"] >= 0) and sim["v"].max() > 5.0
    speed = np.interp(sim["t"], ref[:, 1], np.hypot(ref[:, 5], ref[:, 6]))  # a flat drive: |v_h| = forward speed
    assert np.std(sim["v"] - speed * (sim["v"] @ speed) / (speed @ speed)) < 0.06  # σ 5 cm/s around (1 + ε)·s


def test_reader_round_trips_text_units_and_a_bag(sim, tmp_path):
    f = read_odometer(sim["good"])
    np.testing.assert_allclose(f.speed, sim["v"], atol=1e-6)
    assert np.all(np.isnan(f.sigma)) and f.dropped == 0
    k = read_odometer(sim["kmh"], unit="km/h")
    np.testing.assert_allclose(k.speed, sim["v"], atol=1e-5)
    np.testing.assert_allclose(read_odometer(sim["good"], scale=1.01).speed, sim["v"] / 1.01, atol=1e-6)
    from imunoise.io.bag_write import write_imu_bag

    t = sim["t"]
    lin = np.column_stack([sim["v"], np.zeros((t.size, 2))])
    bag = write_imu_bag(tmp_path / "car.bag", t, np.zeros((t.size, 3)), np.tile([0, 0, 9.8], (t.size, 1)),
                        twists={"/vehicle/speed": (t, lin, np.full((t.size, 3), 0.02**2))})
    b = read_odometer(bag)
    np.testing.assert_allclose(b.t, t, atol=1e-9)
    np.testing.assert_allclose(b.speed, sim["v"], atol=1e-12)
    np.testing.assert_allclose(b.sigma, 0.02)


@pytest.mark.parametrize("case,words", [
    ("neg", "negative speed"),
    ("back", "time goes back"),
    ("kmh", "km/h"),
    ("unix", "Unix time"),
])
def test_bad_speed_files_are_refused_in_one_line(sim, tmp_path, case, words):
    d = sim["dir"]
    out = tmp_path / "o"
    code, err = _run(["nav", "--data", d, "--odometer", sim[case], "--no-plots", "--out", out])
    one_line_error(code, err, "--odometer", words)
    assert not out.exists() or not any(out.iterdir())


def test_nan_speeds_are_dropped_and_counted(sim, tmp_path):
    code, err = _run(["nav", "--data", sim["dir"], "--odometer", sim["nan"], "--no-plots", "--out", tmp_path / "o"])
    assert code == 0, err
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert m["odometer"]["dropped_nan"] == 5 and m["odometer"]["used"] > 1000


def test_reader_refuses_an_unknown_unit_and_scale(sim):
    with pytest.raises(DataError, match="unit 'furlong/h'"):
        read_odometer(sim["good"], unit="furlong/h")
    with pytest.raises(DataError, match="scale factor"):
        read_odometer(sim["good"], scale=0.0)


def test_odometer_through_outages_beats_without_on_a_seeded_drive():
    sc = simulate_scenario(4400, duration_s=400.0, n_stops=2, n_outages=2, streams=("odometer",))
    gnss = sc.gnss.without(sc.windows)

    def end_errors(config, streams=()):
        r = run_ekf(sc.imu, gnss, sc.init, config, streams=streams)
        err = nav_errors(r.t, r.llh, r.vel_ned, r.euler, sc.ref)
        return np.array([err.horizontal[np.searchsorted(err.t, s + length) - 1] for s, length in sc.windows])

    odo = sc.extra["streams"]
    plain, with_odo = end_errors(sc.ekf_config()), end_errors(sc.ekf_config(), odo)
    nhc_cfg = sc.ekf_config().with_(aiding=(NhcConfig(),))
    nhc, nhc_odo = end_errors(nhc_cfg), end_errors(nhc_cfg, odo)
    # measured: plain 174 / 169 m, odometer 54 / 116 m; NHC 49 / 46 m, NHC + odometer 42 / 37 m
    assert with_odo.mean() < 0.7 * plain.mean(), (with_odo, plain)
    assert nhc_odo.mean() < 0.95 * nhc.mean(), (nhc_odo, nhc)


def test_online_applies_the_odometer_and_counts_it(sim, tmp_path):
    out = tmp_path / "on"
    code, err = _run(["online", "--data", sim["dir"], "--odometer", "--out", out])
    assert code == 0, err
    m = json.loads((out / "metrics.json").read_text())["odometer"]
    assert m["file"].endswith("odometer.txt") and m["used"] + m["forced"] > 0.9 * m["fixes"]


def test_an_experiment_takes_the_option_without_a_file(sim, tmp_path):
    code, err = _run(["experiment", "online", "--sim", "--odometer", sim["good"], "--out", tmp_path / "e"])
    one_line_error(code, err, "--odometer", "without FILE")
