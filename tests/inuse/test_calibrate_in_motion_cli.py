"""`imunoise calibrate --in-motion`: refused without GNSS before any work; on the real drive (slow) the model
file and calibration.json carry the in-motion part and the summary prints the factors with intervals."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest

from imunoise.cli import main

DRIVE = Path(__file__).resolve().parents[2] / "data" / "drive_0708"


def test_in_motion_without_gnss_is_one_line_exit_2(tmp_path, capsys):
    imu = tmp_path / "imu.txt"
    imu.write_text("0 0 0 0 0 0 0\n")
    code = main(["calibrate", str(imu), "--in-motion", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and "--in-motion" in err[0] and "--gnss" in err[0]
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_in_motion_on_the_real_drive_writes_the_part(tmp_path, capsys):
    if not (DRIVE / "dataset.json").exists():
        pytest.skip("data/drive_0708 is not in this checkout")
    out = tmp_path / "calib"
    assert main(["calibrate", str(DRIVE), "--complete", "WN+RW", "--in-motion", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    model = json.loads((out / "imu_model.json").read_text())
    part = model["in_motion"]
    assert set(part["axes"]) == {"gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"}
    assert json.loads((out / "calibration.json").read_text())["in_motion"] == part
    assert part["evidence"]["hours_moving"] > 0.05 and part["evidence"]["freq_hz"] == pytest.approx(100.0, rel=1e-3)
    assert "gyro_x: in-use N " in text and (out / "in_motion.png").exists()


# ----------------------------------------------------------------------------------------------------------
# --export with --noise (export's one option) and --scheduler (batch's one option); the files written:
# tests/export/test_calibrate_export_noise.py
# ----------------------------------------------------------------------------------------------------------


def _option(parser, command: str, flag: str):
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return next(a for a in sub.choices[command]._actions if flag in a.option_strings)


def test_calibrate_and_export_share_one_noise_option_and_batch_one_scheduler_option():
    from imunoise.cli import build_parser
    from imunoise.cli.export import NOISE_CHOICES
    from imunoise.export.in_use import NOISE_CHOICES as LIBRARY_CHOICES

    parser = build_parser()
    cal, exp = _option(parser, "calibrate", "--noise"), _option(parser, "export", "--noise")
    assert cal is not exp and (cal.choices, cal.default, cal.help) == (exp.choices, exp.default, exp.help)
    assert (cal.choices, cal.default) == (NOISE_CHOICES, "in-use")
    assert set(NOISE_CHOICES) == set(LIBRARY_CHOICES)
    cal, bat = _option(parser, "calibrate", "--scheduler"), _option(parser, "batch", "--scheduler")
    assert (cal.default, bat.default) == ("sequential", "local")  # no Dask unless asked; batch's own default
    assert cal.help.split(":", 1)[0] != bat.help.split(":", 1)[0]  # each says what it distributes


@pytest.mark.parametrize("extra,says", [(["--noise", "static"], ["--noise static", "--export"]),
                                        (["--scheduler", "local"], ["--scheduler", "--in-motion"]),
                                        (["--in-motion", "--gnss", "g.txt", "--workers", "0"], ["--workers", "got 0"])])
def test_noise_and_scheduler_without_what_they_act_on_are_one_line_exit_2(extra, says, tmp_path, capsys):
    imu = tmp_path / "imu.txt"
    imu.write_text("0 0 0 0 0 0 0\n")
    code = main(["calibrate", str(imu), *extra, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and all(s in err[0] for s in says), err
    assert not (tmp_path / "out").exists()
