"""``imunoise nav --imu-model`` with an in-motion part on the shipped drive: the part is used (metrics say so,
the trajectory changes); the same file without it navigates as before (no in-motion path)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from imunoise.cli import main
from imunoise.noise.model import Model
from imunoise.noise.processes import RW, WN

DRIVE = Path(__file__).resolve().parents[2] / "data" / "drive_0708"


def _entry(white: float, rw: float, unit: str) -> dict:
    return {**Model([WN(sigma2=white), RW(gamma2=rw)]).to_dict(), "freq_hz": 100.0, "unit": unit}


def test_nav_uses_the_in_motion_part(tmp_path):
    if not (DRIVE / "dataset.json").exists():
        pytest.skip("data/drive_0708 is not in this checkout")
    static = {"gyro": _entry(1e-7, 1e-14, "rad/s"), "accel": _entry(1e-4, 1e-10, "m/s^2")}
    part = {"axes": {a: {"white_factor": {"value": 3.0, "ci95": [2.0, 4.0]},
                         "bias": {"model": "gm", "sigma": 5.8e-4, "tau_s": 60.0, "ci95": {}}}
                     for a in ("gyro_x", "gyro_y", "gyro_z")}, "bounds": {}, "evidence": {}}
    runs = {}
    for name, d in (("static", static), ("in_motion", {**static, "in_motion": part})):
        path = tmp_path / f"{name}.json"
        path.write_text(json.dumps(d))
        out = tmp_path / name
        assert main(["nav", "--data", str(DRIVE), "--imu-model", str(path), "--out", str(out), "--no-plots"]) == 0
        runs[name] = (json.loads((out / "metrics.json").read_text()),
                      np.loadtxt(out / "trajectory.nav", usecols=(2, 3)))
    assert runs["static"][0]["in_motion"] is False and runs["in_motion"][0]["in_motion"] is True
    assert not np.array_equal(runs["static"][1], runs["in_motion"][1])
