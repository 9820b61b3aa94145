"""Exports to Kalibr / OpenVINS / ORB-SLAM3 / JSON: exact formulas (SPEC §2), units, round trips."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from imunoise.cli import main
from imunoise.errors import ModelError, UnitError
from imunoise.export import (
    axis_noise,
    export_text,
    format_float,
    parse_inflate,
    read_export,
    sensor_noise,
    write_export,
)
from imunoise.gmwm import GMWMFit, gmwm
from imunoise.imu_model import ImuModel, load_model
from imunoise.model import Model

F = 200.0
AXES = ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]


@pytest.fixture(scope="module")
def base_fit() -> GMWMFit:
    x = Model.parse("WN+RW").with_params({"WN.sigma2": 1e-4, "RW.gamma2": 1e-10}).simulate(2**12, seed=1)
    return gmwm("WN+RW", x, freq=F, unit="rad/s", n_random=4, n_local=2)


def _with(fit: GMWMFit, text: str, params: dict, unit: str) -> GMWMFit:
    d = fit.to_dict()
    d["model"] = text
    d["params"] = params
    d["unit"] = unit
    d["param_cov_u"] = None
    return GMWMFit.from_dict(d)


@pytest.fixture(scope="module")
def imu_model(base_fit) -> ImuModel:
    fits = {}
    for i, axis in enumerate(AXES):
        s = 1.0 + 0.1 * i
        if axis.startswith("gyro"):
            fits[axis] = _with(base_fit, "WN+RW", {"WN.sigma2": 1e-6 * s, "RW.gamma2": 1e-12 * s}, "rad/s")
        else:
            p = {"AR1_1.phi": 0.999, "AR1_1.sigma2": 1e-8 * s, "WN.sigma2": 4e-4 * s, "RW.gamma2": 1e-9 * s}
            fits[axis] = _with(base_fit, "AR1+WN+RW", p, "m/s²")
    return ImuModel.from_fits(fits, source={"topic": "/imu/data"})


def test_axis_noise_matches_spec_formulas(base_fit):
    phi, s2, wn, g2, q2 = 0.995, 2e-8, 3e-5, 4e-12, 1e-6
    fit = _with(
        base_fit,
        "AR1+WN+QN+RW",
        {"AR1_1.phi": phi, "AR1_1.sigma2": s2, "WN.sigma2": wn, "QN.q2": q2, "RW.gamma2": g2},
        "rad/s",
    )
    a = axis_noise(fit, "gyro_x")
    dt = 1 / F
    tc = -dt / math.log(phi)  # SPEC §2 AR1 row
    s2gm = s2 / (1 - phi**2)
    assert a.N == pytest.approx(math.sqrt((wn + 2 * q2) * dt), rel=1e-12)
    assert a.K_rw == pytest.approx(math.sqrt(g2) / math.sqrt(dt), rel=1e-12)
    assert a.K_eq == pytest.approx(math.sqrt(g2 * F + 2 * s2gm / tc), rel=1e-12)
    assert a.gm[0][0] == pytest.approx(tc, rel=1e-12)
    plain = _with(base_fit, "WN+RW", {"WN.sigma2": wn, "RW.gamma2": g2}, "rad/s")
    assert axis_noise(plain).N == pytest.approx(math.sqrt(wn) * math.sqrt(dt), rel=1e-14)  # N = σ·√Δt exactly


def test_sensor_combination_and_inflation(imu_model):
    ns = [axis_noise(imu_model.axes[a]).N for a in AXES[:3]]
    ks = [axis_noise(imu_model.axes[a]).K_eq for a in AXES[:3]]
    g = sensor_noise(imu_model, "gyro")
    assert g.noise_density == max(ns) and g.random_walk == max(ks)
    r = sensor_noise(imu_model, "gyro", combine="rms", inflate=parse_inflate("white=2,rw=10"))
    assert r.raw_noise_density == pytest.approx(math.sqrt(np.mean(np.square(ns))), rel=1e-14)
    assert r.noise_density == 2 * r.raw_noise_density and r.random_walk == 10 * r.raw_random_walk
    assert g.discrete_sigma == pytest.approx(g.noise_density * math.sqrt(F), rel=1e-14)
    with pytest.raises(ModelError, match="white=FACTOR"):
        parse_inflate("2")


@pytest.mark.parametrize("fmt", ["kalibr", "openvins", "orbslam3"])
def test_yaml_round_trip_and_comments(tmp_path, imu_model, fmt):
    path = write_export(imu_model, fmt, tmp_path / f"{fmt}.yaml", inflate="white=2,rw=10")
    back = read_export(path)
    g = sensor_noise(imu_model, "gyro", inflate={"white": 2, "rw": 10})
    a = sensor_noise(imu_model, "accel", inflate={"white": 2, "rw": 10})
    keys = {
        "kalibr": ("gyroscope_noise_density", "gyroscope_random_walk", "accelerometer_noise_density",
                   "accelerometer_random_walk", "update_rate"),
        "openvins": ("gyroscope_noise_density", "gyroscope_random_walk", "accelerometer_noise_density",
                     "accelerometer_random_walk", "update_rate"),
        "orbslam3": ("IMU.NoiseGyro", "IMU.GyroWalk", "IMU.NoiseAcc", "IMU.AccWalk", "IMU.Frequency"),
    }[fmt]  # fmt: skip
    # read back equals, bit for bit
    assert [back[k] for k in keys] == [g.noise_density, g.random_walk, a.noise_density, a.random_walk, F]
    assert all(isinstance(back[k], float) for k in keys)
    if fmt != "orbslam3":
        assert back["rostopic"] == "/imu/data"
    text = path.read_text()
    for line in text.splitlines():
        if re.match(r"\s*(gyro|accel|IMU\.Noise|IMU\.\w+Walk)", line):
            assert "continuous" in line and "discrete" in line and "sqrt(Hz)" in line, line
            assert "(fit) x" in line  # inflation shown beside the value
    assert "NOT the Allan-variance minimum" in text and "K_eq = sqrt(gamma^2*f" in text


def test_json_export_keeps_full_model(tmp_path, imu_model):
    path = write_export(imu_model, "json", tmp_path / "n.json")
    d = read_export(path)
    assert ImuModel.from_dict(d["model"]).to_dict() == imu_model.to_dict()
    assert d["sensors"]["gyro"]["noise_density"] == sensor_noise(imu_model, "gyro").noise_density
    assert d["sensors"]["accel"]["random_walk_unit"] == "m/s^3/sqrt(Hz)"


def test_model_file_round_trip_and_single_axis(tmp_path, imu_model, base_fit):
    p = imu_model.save(tmp_path / "imu_model.json")
    m = load_model(p)
    assert isinstance(m, ImuModel) and m.to_dict() == json.loads(p.read_text())
    assert m.axes["gyro_x"] == imu_model.fit("gyro_x").to_dict()  # per-axis dicts are GMWMFit.to_dict()
    base_fit.save(str(tmp_path / "model.json"))
    single = load_model(tmp_path / "model.json")
    with pytest.raises(ModelError, match="--sensor"):
        export_text(single, "kalibr")
    text = export_text(single, "kalibr", sensor="gyro")
    assert "# accelerometer_noise_density: not exported" in text
    assert read_export_text(text)["gyroscope_noise_density"] == axis_noise(base_fit).N
    with pytest.raises(UnitError, match="needs m/s²"):
        export_text(single, "kalibr", sensor="accel")  # the fit is in rad/s


def read_export_text(text: str) -> dict:
    import yaml

    return yaml.safe_load(text)


def test_format_float_is_yaml_and_opencv_real():
    import yaml

    for x in (1e-5, 2.0, 1.2345678901234567e-7, 0.1 + 0.2):
        s = format_float(x)
        assert "." in s and re.search(r"e[+-]\d\d", s) and yaml.safe_load(f"v: {s}")["v"] == x


def test_cli_export(tmp_path, imu_model, capsys):
    p = imu_model.save(tmp_path / "imu_model.json")
    assert main(["export", str(p), "--to", "openvins", "--inflate", "white=3"]) == 0
    back = read_export(tmp_path / "kalibr_imu_chain.yaml")
    assert back["gyroscope_noise_density"] == 3 * sensor_noise(imu_model, "gyro").raw_noise_density
    assert main(["export", str(p), "--to", "orbslam3", "--out", "-"]) == 0
    assert "IMU.NoiseGyro:" in capsys.readouterr().out
    assert main(["export", str(tmp_path / "missing.json")]) == 2
