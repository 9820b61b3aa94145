"""`imunoise calibrate --in-motion --export TOOL --noise in-use|static` writes, for every tool, the file `imunoise
export MODEL --to TOOL --noise ...` writes from the saved model (byte for byte but the header's time stamp), and
the tool's own reads (tests/export/tool_reads.py) find the pair ``--noise`` asks for; the same calibration with
``--scheduler local --workers 2`` (the drives' runs on Dask) gives the same in-motion part."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from tool_reads import carried_nk, tool_reads

from imunoise.cli import main
from imunoise.export import DEFAULT_FILENAMES, model_sensors
from imunoise.noise.imu_model import load_model

TOOLS = ("kalibr", "openvins", "orbslam3", "vins", "lio-sam", "fast-lio")


@pytest.fixture(scope="module")
def sim_drive(tmp_path_factory) -> Path:
    """A 240 s simulated drive (seed 7301, two stops, the default motion law) as a dataset folder."""
    out = tmp_path_factory.mktemp("inuse") / "drive"
    assert main(["simulate", "--duration", "240", "--stops", "2", "--static-start", "40", "--seed", "7301",
                 "--out", str(out)]) == 0
    return out


def _without_stamp(text: str) -> list[str]:
    return [ln for ln in text.splitlines() if "written by imunoise" not in ln]  # the header's time stamp


@pytest.mark.slow  # two calibrations with the in-motion estimate: about 3 minutes on 2 cores
def test_calibrate_export_writes_what_export_noise_writes_and_dask_changes_nothing(sim_drive, tmp_path, capsys):
    export = [x for t in TOOLS for x in ("--export", t)]
    base = ["calibrate", str(sim_drive), "--complete", "WN+RW", "--in-motion", *export]
    runs = {"in-use": ([], tmp_path / "serial"), "static": (["--scheduler", "local", "--workers", "2"],
                                                           tmp_path / "dask")}
    for noise, (extra, out) in runs.items():
        assert main([*base, "--noise", noise, *extra, "--out", str(out)]) == 0
    capsys.readouterr()
    parts = [json.loads((out / "imu_model.json").read_text())["in_motion"] for _, out in runs.values()]
    assert parts[0] == parts[1]  # the Dask run's estimate is the serial one, number for number
    assert set(parts[0]["axes"]) == {"gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"}
    for noise, (_, out) in runs.items():
        model_path = out / "imu_model.json"
        model = load_model(model_path)
        pairs = model_sensors(model, None, "max", None, noise=noise)
        rate = pairs["gyro"].freq_hz
        for fmt in TOOLS:
            written = out / DEFAULT_FILENAMES[fmt]
            again = tmp_path / f"again_{noise}_{fmt}"
            assert main(["export", str(model_path), "--to", fmt, "--noise", noise, "--out", str(again)]) == 0
            assert _without_stamp(written.read_text()) == _without_stamp(again.read_text()), fmt
            got = carried_nk(fmt, tool_reads(fmt, written), rate)
            for s in ("gyro", "accel"):
                want = (pairs[s].noise_density, pairs[s].random_walk)
                assert got[s] == pytest.approx(want, rel=1e-6 if fmt == "lio-sam" else 1e-9), (fmt, noise, s)
            assert ("in-use N = " in written.read_text()) == (noise == "in-use")
