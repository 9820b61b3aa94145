"""`imunoise nav` end to end on a short simulated dataset folder
(docs/guide/theory.rst, 'Navigation filter' and 'Interfaces')."""

from __future__ import annotations

import json

import pytest

from imunoise.cli import main
from imunoise.sim.drive import DriveConfig, simulate_drive


@pytest.fixture(scope="module")
def sim_dir(tmp_path_factory):
    cfg = DriveConfig(
        duration_s=150.0,
        n_stops=1,
        static_s=35.0,
        gnss_rate_hz=5.0,
        gnss_sigma_m=(0.05, 0.05, 0.1),
        lever_arm_m=(0.5, -0.2, -1.0),
        outages=[(60.0, 20.0), (110.0, 20.0)],
        seed=2,
    )
    d = simulate_drive(cfg, "mems", seed=2)
    return d.write(tmp_path_factory.mktemp("sim"))


@pytest.mark.slow
def test_nav_outage_runs_writes_everything(sim_dir, tmp_path, capsys):
    out = tmp_path / "nav"
    rc = main(["nav", "--data", str(sim_dir), "--outage-runs", "--out", str(out)])
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    for key in (
        "horizontal_rms_m",
        "horizontal_p95_m",
        "horizontal_max_m",
        "vertical_rms_m",
        "velocity_rms_mps",
        "ecef_rms_m",
        "outages",
        "elapsed_s",
        "realtime_factor",
    ):
        assert key in m
    assert len(m["outages"]) == 2
    assert all(o["end_horizontal_m"] is not None for o in m["outages"])
    assert m["horizontal_rms_m"] < 0.5  # 5 cm GNSS, lever arm applied
    for f in ("trajectory.nav", "trajectory.png", "errors.png", "biases.png", "outage_1/trajectory.nav"):
        assert (out / f).exists(), f
    assert "mean end-of-outage" in capsys.readouterr().out


def test_nav_bad_start_is_a_one_line_error(sim_dir, tmp_path, capsys):
    rc = main(["nav", "--data", str(sim_dir), "--start", "1", "--no-plots", "--out", str(tmp_path / "x")])
    assert rc == 2
    assert "outside the IMU data" in capsys.readouterr().err


def test_nav_with_model_json(sim_dir, tmp_path):
    truth = json.loads((sim_dir / "truth.json").read_text())
    models = {"gyro": truth["models"]["gyro_x"], "accel": truth["models"]["accel_x"]}
    (tmp_path / "model.json").write_text(json.dumps(models))
    rc = main(
        [
            "nav",
            "--data",
            str(sim_dir),
            "--model",
            str(tmp_path / "model.json"),
            "--no-plots",
            "--out",
            str(tmp_path / "o"),
        ]
    )
    assert rc == 0
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert m["model"].endswith("model.json") and m["horizontal_rms_m"] < 0.5


def test_model_json_layouts_and_units(tmp_path):
    from imunoise.errors import UnitError
    from imunoise.nav.defaults import load_axis_models

    fit = {
        "kind": "imunoise.fit",
        "model": "AR1 + WN",
        "params": {"AR1_1.phi": 0.999, "AR1_1.sigma2": 1e-8, "WN.sigma2": 1e-6},
        "freq_hz": 200.0,
        "unit": "rad/s",
    }
    acc = {**fit, "unit": "m/s²"}
    per_axis = load_axis_models({"gyro": {"x": fit, "y": fit, "z": fit}, "accel": acc}, 100.0)
    assert [m.freq for m in per_axis] == [200.0] * 6
    assert str(per_axis[0]) == "AR1 + WN"
    partial = load_axis_models({"gyro_z": {**fit, "unit": "u"}}, 100.0)  # others: plain default
    assert str(partial[2]) == "AR1 + WN" and partial[0].freq == 100.0
    with pytest.raises(UnitError, match="deg/s"):
        load_axis_models({"gyro": {**fit, "unit": "deg/s"}, "accel": acc}, 100.0)


def test_nav_zupt_at_detected_stops(sim_dir, tmp_path):
    rc = main(["nav", "--data", str(sim_dir), "--zupt", "--no-plots", "--out", str(tmp_path / "z")])
    assert rc == 0
    m = json.loads((tmp_path / "z" / "metrics.json").read_text())
    assert m["zupt"] is True and m["horizontal_rms_m"] < 0.5
