"""`imunoise calibrate` on inputs that used to pass silently: a log without a speed source whose "stops" are
steady cruising (refused in one line naming --gnss/--ref), and time stamps that `fit` warns about (the same
warnings, printed and kept in imu_model.json and calibration.json)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from imunoise.calibrate import ImuLog, detect_stops
from imunoise.calibrate.stops import implausible_stops
from imunoise.cli import main
from imunoise.cli.options import parse_units
from imunoise.io.imu_input import read_imu_source
from imunoise.sim import DriveConfig, simulate_drive

COLUMNS = "gyro_x=gx,gyro_y=gy,gyro_z=gz,accel_x=ax,accel_y=ay,accel_z=az"
UNITS = "gyro=rad/s,accel=m/s^2"


def write_csv(path, t, g, a):
    np.savetxt(path, np.column_stack([t, g, a]), delimiter=",", fmt="%.17g", header="t,gx,gy,gz,ax,ay,az",
               comments="")
    return path


@pytest.fixture(scope="module")
def cruising():
    """15 min, only sub-second stops, moving noise = the static model (law none): every "stop" a detector
    finds is steady cruising."""
    cfg = DriveConfig(duration_s=900.0, n_stops=6, stop_range_s=(0.5, 0.9), static_s=0.5, motion_noise="none")
    return simulate_drive(cfg, "WN+RW", seed=3605)


def test_cruising_without_speed_is_refused_in_one_line(cruising, tmp_path, capsys):
    g, a = cruising.imu.rates()
    path = write_csv(tmp_path / "smooth.csv", cruising.imu.t, g, a)
    code = main(["calibrate", str(path), "--columns", COLUMNS, "--units", UNITS, "--time-column", "t",
                 "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    line = err[-1]
    assert "smooth.csv" in line and "stops in 15.0 min" in line and "--gnss or --ref" in line, line
    assert "Traceback" not in "\n".join(err)
    assert not (tmp_path / "out" / "imu_model.json").exists()


def test_the_same_cruise_with_its_speed_is_not_taken_for_stops(cruising):
    """With the reference speed the speed check drops the cruise: what is kept is the drive's true stops (its
    final stop at rest), not judged by the stop rate."""
    g, a = cruising.imu.rates()
    ref = cruising.reference
    speed = (np.asarray(ref.t, dtype=float), np.linalg.norm(np.asarray(ref.vel_ned)[:, :2], axis=1))
    log = ImuLog("smooth", np.asarray(cruising.imu.t, dtype=float), g, a, float(cruising.imu.rate_hz), speed)
    ls = detect_stops(log)
    assert implausible_stops(ls) is None and 1 <= len(ls.stops) < 10
    kept = np.concatenate([cruising.static_mask[s.i0 : s.i1] for s in ls.stops])
    assert kept.all()  # every kept sample at rest
    no_speed = detect_stops(ImuLog("smooth", log.t, g, a, log.rate_hz))
    assert implausible_stops(no_speed) is not None and len(no_speed.stops) > 15


def test_stop_rate_option_is_checked(tmp_path, capsys):
    assert main(["calibrate", "x.csv", "--max-stop-rate", "0", "--out", str(tmp_path / "o")]) == 2
    assert "--max-stop-rate" in capsys.readouterr().err.strip().splitlines()[-1]


def test_clock_step_and_repeated_stamps_are_warned_and_recorded_as_fit_does(tmp_path, capsys):
    cfg = DriveConfig(duration_s=300.0, n_stops=3, stop_range_s=(20.0, 40.0), static_s=40.0)
    d = simulate_drive(cfg, "WN+RW", seed=3606)
    g, a = d.imu.rates()
    t = np.asarray(d.imu.t, dtype=float)
    rows = np.column_stack([t, g, a])
    # a clock step: a block of 200 samples written after the 300 that follow it; 50 rows written twice
    rows = np.concatenate([rows[:20000], rows[20200:20500], rows[20000:20200], rows[20500:]])
    rows = np.insert(rows, np.arange(25000, 25050), rows[25000:25050], axis=0)
    path = write_csv(tmp_path / "stamps.csv", rows[:, 0], rows[:, 1:4], rows[:, 4:])
    src = {"columns": COLUMNS, "units": parse_units(UNITS), "time_column": "t"}
    with warnings.catch_warnings(record=True) as caught:  # what `fit` reads and warns about
        warnings.simplefilter("always")
        read_imu_source(path, **src)
    fit_msgs = list(dict.fromkeys(str(w.message) for w in caught))
    assert any("out-of-order" in m for m in fit_msgs) and any("duplicated" in m for m in fit_msgs)
    out = tmp_path / "out"
    code = main(["calibrate", str(path), "--columns", COLUMNS, "--units", UNITS, "--time-column", "t",
                 "--complete", "WN+RW", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 0, err
    for m in fit_msgs:
        assert f"warning: {m}" in err
    kept = json.loads((out / "calibration.json").read_text())["warnings"]
    assert kept == fit_msgs
    assert json.loads((out / "imu_model.json").read_text())["source"]["warnings"] == fit_msgs
