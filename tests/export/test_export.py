"""Exports to Kalibr / OpenVINS / ORB-SLAM3 / JSON: exact formulas (docs/guide/theory.rst, 'Latent processes'), units,
round trips."""

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
from imunoise.noise.estimator import GMWMFit, gmwm
from imunoise.noise.imu_model import ImuModel, load_model
from imunoise.noise.model import Model

F = 200.0
AXES = ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]


@pytest.fixture(scope="module")
def base_fit() -> GMWMFit:
    x = Model.parse("WN+RW").with_params({"WN.sigma2": 1e-4, "RW.gamma2": 1e-10}).simulate(2**12, seed=1)
    return gmwm("WN+RW", x, freq=F, unit="rad/s", n_random=4, n_local=2)


def _with(fit: GMWMFit, text: str, params: dict, unit: str) -> GMWMFit:
    """``fit`` with another model and parameters, its empirical WV (and band, at the same relative width) set
    to that model's WV: the export gate checks a fit against its data, and these are exact-model fits."""
    d = fit.to_dict()
    d["model"] = text
    d["params"] = params
    d["unit"] = unit
    d["param_cov_u"] = None
    g = GMWMFit.from_dict(d)
    ratio = g.theoretical_wv / g.wv.variance
    wv = dict(d["wv"])
    for key in ("variance", "ci_low", "ci_high"):
        wv[key] = list(np.asarray(wv[key], dtype=float) * ratio)
    if wv.get("cov") is not None:  # the covariance of ν̂ scaled alike: r_i r_j cov_ij
        n = ratio.size
        wv["cov"] = list((np.asarray(wv["cov"], dtype=float).reshape(n, n) * np.outer(ratio, ratio)).ravel())
    d["wv"] = wv
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


def test_axis_noise_closed_forms_where_exact(base_fit):
    """WN, QN, RW and an AR1 faster than one update keep their exact closed forms
    (docs/guide/theory.rst, 'Latent processes' and 'Interfaces')."""
    phi, s2, wn, g2, q2 = 0.1, 2e-6, 3e-5, 4e-12, 1e-6  # T_c = 2.2 ms < Δt = 5 ms
    fit = _with(
        base_fit,
        "AR1+WN+QN+RW",
        {"AR1_1.phi": phi, "AR1_1.sigma2": s2, "WN.sigma2": wn, "QN.q2": q2, "RW.gamma2": g2},
        "rad/s",
    )
    a = axis_noise(fit, "gyro_x")
    dt = 1 / F
    assert a.N == pytest.approx(math.sqrt((wn + 2 * q2 + s2 / (1 - phi) ** 2) * dt), rel=1e-12)
    assert a.K == a.K_eq == a.K_rw == pytest.approx(math.sqrt(g2) / math.sqrt(dt), rel=1e-12)
    assert a.worst_ratio == 1.0 and a.tau_range_s == (dt, fit.wv.scales[-1] / 2 / F)
    plain = _with(base_fit, "WN+RW", {"WN.sigma2": wn, "RW.gamma2": g2}, "rad/s")
    assert axis_noise(plain).N == pytest.approx(math.sqrt(wn) * math.sqrt(dt), rel=1e-14)  # N = σ·√Δt exactly


def test_repro_fast_ar1_never_zero_density(base_fit):
    """The issue's repro: a fast AR1 that absorbed the white noise (WN at the bound) goes to N, not to K."""
    tc, sgm = 0.005, 0.006
    phi = math.exp(-1 / (tc * F))
    p = {"AR1_1.phi": 0.9999, "AR1_1.sigma2": 1e-12, "AR1_2.phi": phi, "AR1_2.sigma2": sgm**2 * (1 - phi**2),
         "WN.sigma2": 1e-60, "RW.gamma2": 1e-12}  # fmt: skip
    a = axis_noise(_with(base_fit, "2*AR1+WN+RW", p, "rad/s"), "gyro_x")
    assert a.N == pytest.approx(sgm * math.sqrt((1 + phi) / (1 - phi) / F), rel=1e-3)
    assert a.K >= a.K_rw > 0 and a.K < 0.1 * math.sqrt(2 * sgm**2 / tc)  # q_c = 2σ²/T_c is not added to K
    assert [r.slot for r in a.equivalent.routes] == ["K", "N", "N", "K"]  # T_c = 50 s > horizon 5.12 s: K


def test_unidentified_slots_never_write_zero(base_fit):
    wn_only = _with(base_fit, "WN", {"WN.sigma2": 1e-6}, "rad/s")
    a = axis_noise(wn_only, "gyro_x")
    assert a.K > 0 and any("no random walk" in n for n in a.notes) and a.worst_ratio <= 1.5 + 1e-9
    rw_only = _with(base_fit, "RW", {"RW.gamma2": 1e-10}, "rad/s")
    with pytest.raises(ModelError, match="no white-noise-like process"):
        axis_noise(rw_only, "gyro_x")


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
    if fmt == "openvins":  # what OpenVINS >= v2.7 also requires (test_export_clients.py reads it as OpenVINS does)
        eye = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
        assert back["model"] == "kalibr" and back["Tw"] == back["Ta"] == back["R_IMUtoGYRO"] == eye
        assert back["Tg"] == [[0.0] * 3] * 3
    text = path.read_text()
    for line in text.splitlines():
        if re.match(r"\s*(gyro|accel|IMU\.Noise|IMU\.\w+Walk)", line):
            assert "continuous" in line and "discrete" in line and "sqrt(Hz)" in line, line
            assert "(fit) x" in line  # inflation shown beside the value
    assert "NOT the Allan-variance minimum" in text and "matched on tau = " in text
    assert text.count("worst AV ratio exported/model") == 2  # beside each written pair


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
    # a gyro-only fit cannot make a file Kalibr reads (ImuParameters needs the accelerometer keys): refused,
    # naming the keys; the gyro block alone on request (--sensor, partial=True)
    with pytest.raises(ModelError, match="needs accelerometer_noise_density, accelerometer_random_walk"):
        export_text(single, "kalibr")
    text = export_text(single, "kalibr", partial=True)  # rad/s: a gyro, no --sensor needed
    assert read_export_text(text) == read_export_text(export_text(single, "kalibr", sensor="gyro", partial=True))
    assert "SENSOR BLOCK ONLY (gyro)" in text
    unitless = _with(base_fit, "WN+RW", base_fit.params, "u")
    with pytest.raises(ModelError, match="--sensor"):
        export_text(unitless, "kalibr")
    by_name = _with(base_fit, "WN+RW", base_fit.params, "u")
    by_name.extra["column"] = "accel_z"
    assert "accelerometer_noise_density: " in export_text(by_name, "kalibr", partial=True)
    assert "# accelerometer_noise_density: not exported" in text
    assert read_export_text(text)["gyroscope_noise_density"] == axis_noise(base_fit).N
    with pytest.raises(UnitError, match="needs m/s²"):
        export_text(single, "kalibr", sensor="accel", partial=True)  # the fit is in rad/s


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


def test_cli_export_refusals_and_report(tmp_path, imu_model, capsys):
    p = imu_model.save(tmp_path / "imu_model.json")
    before = p.read_text()
    capsys.readouterr()
    assert main(["export", str(p), "--to", "json", "--out", str(p)]) == 2  # never over its own input
    assert p.read_text() == before and "input model file" in capsys.readouterr().err
    partial = json.loads(before)
    del partial["axes"]["gyro_x"]["model"]
    (tmp_path / "partial.json").write_text(json.dumps(partial))
    assert main(["export", str(tmp_path / "partial.json"), "--out", "-"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "incomplete" in err and "'model'" in err
    assert main(["export", str(p), "--out", str(tmp_path / "k.yaml"), "--horizon", "5"]) == 0
    err = capsys.readouterr().err
    assert "gyro_x: WN + RW" in err and "WN -> N" in err and "RW -> K" in err and "AR1_1 -> N+K" in err
    assert "matched on tau = 0.005..5 s" in (tmp_path / "k.yaml").read_text()


def test_cli_warns_when_the_pair_cannot_follow_the_model(tmp_path, base_fit, capsys):
    """A bias-instability bump inside the range: worst AV ratio > 2 -> a warning on stderr and in the file."""
    p = {"AR1_1.phi": math.exp(-1 / (0.5 * F)), "AR1_1.sigma2": 1e-6 * (1 - math.exp(-2 / (0.5 * F))),
         "WN.sigma2": 1e-8, "RW.gamma2": 1e-20}  # fmt: skip
    fit = _with(base_fit, "AR1+WN+RW", p, "rad/s")
    fit.save(str(tmp_path / "model.json"))
    capsys.readouterr()
    # the bump also leaves no (N, K) pair within 2x of the data: the pair gate refuses it unless --force
    assert main(["export", str(tmp_path / "model.json"), "--sensor", "gyro", "--force", "--out",
                 str(tmp_path / "imu.yaml")]) == 0
    err = capsys.readouterr().err
    assert "warning: gyro: the exported pair's Allan variance is" in err
    text = (tmp_path / "imu.yaml").read_text()
    assert "(> 2: WARNING)" in text and axis_noise(fit).worst_ratio > 2


def test_write_export_into_updates_in_place(tmp_path, imu_model):
    """``write_export(..., into=FILE)``: the additive keyword of the one writer the fit/calibrate plumbing calls."""
    from pathlib import Path

    src = Path(__file__).resolve().parents[1] / "fixtures" / "kalibr_imu.yaml"
    path = tmp_path / "imu.yaml"
    path.write_bytes(src.read_bytes())
    assert write_export(imu_model, "kalibr", tmp_path / "ignored.yaml", into=path, source="x") == path
    back = read_export(path)
    assert back["gyroscope_noise_density"] == sensor_noise(imu_model, "gyro").noise_density
    assert back["rostopic"] == "/imu/data" and not (tmp_path / "ignored.yaml").exists()
    assert (tmp_path / "imu.yaml.bak").read_bytes() == src.read_bytes()
