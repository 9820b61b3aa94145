"""How long to record in `fit` and `calibrate`: the line per axis with units, the JSON block in the model file /
calibration.json, the plot in report.html, and a one-line error (exit 2) for a bad --target / --target-horizon."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import one_line_error
from imunoise.cli import main
from imunoise.noise.model import Model
from imunoise.noise.processes import RW, WN

F = 100.0


@pytest.fixture(scope="module")
def csv(tmp_path_factory):
    x = Model([WN(sigma2=(1.5e-4) ** 2 * F), RW(gamma2=(2e-5) ** 2 / F)]).simulate(2**17, seed=4330)
    p = tmp_path_factory.mktemp("rl") / "gz.csv"
    np.savetxt(p, x)
    return p


def test_fit_prints_the_line_and_writes_the_block(csv, tmp_path, capsys):
    out = tmp_path / "fit"
    code = main(["fit", str(csv), "--freq", "100", "--model", "WN+RW", "--units", "rad/s", "--target", "5",
                 "--target-horizon", "3600", "--out", str(out)])
    cap = capsys.readouterr()
    assert code == 0, cap.err
    line = next(s for s in cap.out.splitlines() if ": record " in s)
    assert "record 21.8 min: N ±" in line and "%, K ±" in line and "horizon" in line
    assert "for ±5 %: N " in line and "horizon 60 min needs a record of " in line
    block = json.loads((out / "model.json").read_text())["extra"]["record_length"]
    assert block["record_s"] == pytest.approx(2**17 / F, abs=0.02)
    assert block["target_pct"] == 5.0 and block["target_horizon_s"] == 3600.0
    assert 0 < block["at_record"]["N_pct"] < block["at_record"]["K_pct"]
    k_need = block["length_for_target_s"]["K"]
    assert k_need > block["record_s"]  # ±5 % on K takes longer than 22 min of this gyro
    assert f"K {k_need / 3600:.3g} h" in line
    assert len(block["curve"]["length_s"]) == len(block["curve"]["K_pct"]) >= 9


@pytest.mark.parametrize("flag,value", [("--target", "0"), ("--target", "-3"), ("--target", "nan"),
                                        ("--target-horizon", "0"), ("--target-horizon", "nan")])
@pytest.mark.parametrize("command", ["fit", "calibrate"])
def test_bad_target_is_one_line_and_exit_2(csv, tmp_path, capsys, command, flag, value):
    args = [command, str(csv), flag, value, "--out", str(tmp_path / "o")]
    if command == "fit":
        args[2:2] = ["--freq", "100", "--model", "WN"]
    try:
        code = main(args)
    except SystemExit as e:  # nan is refused while the arguments are parsed (argparse's own exit 2)
        code = e.code
    one_line_error(code, capsys.readouterr().err, flag)
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


def test_calibrate_states_the_static_time_and_plots_it(tmp_path, capsys):
    from imunoise.io.navinput import write_nav_bag
    from imunoise.sim import DriveConfig, simulate_drive

    cfg = DriveConfig(duration_s=300.0, n_stops=3, stop_range_s=(20.0, 40.0), static_s=40.0)
    d = simulate_drive(cfg, "WN+RW", seed=4331)
    bag = write_nav_bag(tmp_path / "drive.bag", d.imu, d.gnss, week=cfg.gps_week, imu_topic="/imu0")
    out = tmp_path / "calib"
    code = main(["calibrate", str(bag), "--complete", "WN+RW", "--target-horizon", "100", "--out", str(out)])
    cap = capsys.readouterr()
    assert code == 0, cap.err
    lines = [s for s in cap.out.splitlines() if "static (pooled stops)" in s]
    assert [s.split(":")[0] for s in lines] == ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]
    assert all("horizon 100 s needs a stop of 5.46 min" in s for s in lines)
    cal = json.loads((out / "calibration.json").read_text())
    model = json.loads((out / "imu_model.json").read_text())
    for ax, block in cal["record_length"].items():
        assert block["pooled_stops"] and block["record_s"] == pytest.approx(cal["static_s"])
        assert math.isfinite(block["at_record"]["N_pct"]) and block["at_record"]["N_pct"] > 0
        assert model["source"]["record_length"][ax]["record_s"] == block["record_s"]
    html = (out / "report.html").read_text()
    assert "How long to record" in html and (out / "record_length.png").exists()
