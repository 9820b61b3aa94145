"""VINS, LIO-SAM and FAST-LIO files read as the tools read them, with our values in force.

Each read is reproduced from the tool's source with the tool's parser, and the tool's use of the values (its
covariance propagation per IMU sample) is replayed to check that a written file makes the tool's covariance grow
as the continuous-time model does: N²·dt per sample for white noise, K²·dt for the bias random walk.

Sources (commit read in brackets):
- VINS-Fusion [HKUST-Aerial-Robotics/VINS-Fusion 3d6cfb6, 939f012]: vins_estimator/src/estimator/parameters.cpp
  readParameters() l.77 ``cv::FileStorage fsSettings(config_file, READ)``, l.93 ``USE_IMU = fsSettings["imu"]``,
  l.99-102 ``ACC_N = fsSettings["acc_n"]``, ``ACC_W``, ``GYR_N``, ``GYR_W`` (FileNode -> double: a missing or
  non-numeric key reads 0); vins_estimator/src/factor/integration_base.h l.30-36 ``noise`` = ACC_N² on rows 0 and
  6 (the two samples of a step), GYR_N² on 3 and 9, ACC_W² on 12, GYR_W² on 15; midPointIntegration() l.117-129
  ``V.block<3,3>(6,0) = 0.5*R*dt``, ``V.block<3,3>(6,6) = 0.5*R*dt``, ``V.block<3,3>(3,3) = V.block<3,3>(3,9) =
  0.5*I*dt``, ``V.block<3,3>(9,12) = V.block<3,3>(12,15) = I*dt``; l.134 ``covariance = F*cov*F' + V*noise*V'``.
  VINS-Mono's vins_estimator/src/parameters.cpp reads the same four keys the same way.
- LIO-SAM [TixiaoShan/LIO-SAM, ROS 1 master]: include/utility.h ParamServer()
  ``nh.param<float>("lio_sam/imuAccNoise", imuAccNoise, 0.01)`` and imuGyrNoise, imuAccBiasN, imuGyrBiasN (a
  missing key silently takes the default); config/params.yaml is loaded by launch/run.launch with rosparam, whose
  YAML parser is PyYAML; src/imuPreintegration.cpp ``p->accelerometerCovariance = I*pow(imuAccNoise, 2); // acc
  white noise in continuous`` and the bias BetweenFactor ``Sigmas(sqrt(imuIntegratorOpt_->deltaTij()) *
  noiseModelBetweenBias)``; GTSAM gtsam/navigation/ImuFactor.cpp integrateMeasurement() ``preintMeasCov_ +=
  B * (aCov / dt) * B'`` with B = R*dt on the velocity.
- FAST-LIO [hku-mars/FAST_LIO 34b50d9]: src/laserMapping.cpp ``nh.param<double>("mapping/acc_cov", acc_cov, 0.1)``
  and gyr_cov, b_acc_cov, b_gyr_cov (defaults when missing); config/avia.yaml loaded by launch/mapping_avia.launch
  with rosparam (PyYAML); src/IMU_Processing.hpp UndistortPcl() ``Q.block<3,3>(3,3).diagonal() = cov_acc`` (and
  cov_gyr, cov_bias_gyr, cov_bias_acc) then ``kf_state.predict(dt, Q, in)`` per IMU sample;
  include/IKFoM_toolkit/esekfom/esekfom.hpp predict() ``P_ = F_x1*P_*F_x1' + (dt*f_w_final)*Q*(dt*f_w_final)'``.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from imunoise.cli import main
from imunoise.export import export_text, sensor_noise
from imunoise.noise.estimator import gmwm
from imunoise.noise.imu_model import ImuModel
from imunoise.noise.model import Model

F = 200.0
DT = 1.0 / F
FIX = Path(__file__).resolve().parents[1] / "fixtures"
AXES = ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]
KEYS = {
    "vins": ("acc_n", "acc_w", "gyr_n", "gyr_w"),
    "lio-sam": ("imuAccNoise", "imuAccBiasN", "imuGyrNoise", "imuGyrBiasN"),
    "fast-lio": ("acc_cov", "b_acc_cov", "gyr_cov", "b_gyr_cov"),
}
STOCK = {"vins": "vins_fusion_euroc_stereo_imu_config.yaml", "lio-sam": "lio_sam_params.yaml",
         "fast-lio": "fast_lio_avia.yaml"}  # fmt: skip


@pytest.fixture(scope="module")
def model() -> ImuModel:
    fits = {}
    for i, a in enumerate(AXES):
        gyro = a.startswith("gyro")
        s = 1.0 + 0.1 * i
        p = {"WN.sigma2": (1e-6 if gyro else 4e-4) * s, "RW.gamma2": (1e-12 if gyro else 1e-9) * s}
        x = Model.parse("WN+RW").with_params(p).simulate(2**12, seed=3)
        fits[a] = gmwm("WN+RW", x, freq=F, unit="rad/s" if gyro else "m/s²", n_random=4, n_local=2)
    return ImuModel.from_fits(fits, source={"topic": "/sensors/imu"})


@pytest.fixture(scope="module")
def nk(model) -> dict[str, tuple[float, float]]:
    """The continuous-time (N, K) per sensor, as Kalibr's file would carry them."""
    return {s: (sensor_noise(model, s).noise_density, sensor_noise(model, s).random_walk) for s in ("accel", "gyro")}


# ----------------------------------------------------------------------------------------------------------
# the readers, reproduced (module docstring)
# ----------------------------------------------------------------------------------------------------------
def vins_reads(fs: cv2.FileStorage) -> dict[str, float]:
    """readParameters(): ``ACC_N = fsSettings["acc_n"]`` ... (a FileNode read as double)."""
    assert fs.isOpened()
    keys = list(fs.root().keys())
    assert len(keys) == len(set(keys)), "duplicate keys: OpenCV reads the first"
    out = {}
    for k in KEYS["vins"]:
        node = fs.getNode(k)
        assert node.isReal(), k  # missing or text -> VINS silently uses 0
        out[k] = node.real()
    return out


def ros_reads(text: str, fmt: str) -> dict[str, float]:
    """rosparam load (PyYAML) then nh.param<float|double>("<block>/<key>"): a number, else the default."""
    data = yaml.safe_load(text)
    block = data["lio_sam" if fmt == "lio-sam" else "mapping"]
    out = {}
    for k in KEYS[fmt]:
        assert isinstance(block[k], float), k  # a string would not be read as a number
        out[k] = float(np.float32(block[k])) if fmt == "lio-sam" else block[k]  # LIO-SAM: nh.param<float>
    return out


def vins_step_cov(acc_n: float, acc_w: float, gyr_n: float, gyr_w: float, dt: float = DT) -> np.ndarray:
    """One midPointIntegration() step of ``dt`` [s]: V*noise*V' (R = I, zero rates: the F-terms vanish)."""
    noise = np.diag(np.repeat([acc_n**2, gyr_n**2, acc_n**2, gyr_n**2, acc_w**2, gyr_w**2], 3))
    V = np.zeros((15, 18))
    eye = np.eye(3)
    V[3:6, 3:6] = V[3:6, 9:12] = 0.5 * eye * dt  # rotation from gyr_0, gyr_1
    V[6:9, 0:3] = V[6:9, 6:9] = 0.5 * eye * dt  # velocity from acc_0, acc_1
    V[0:3, 0:3] = V[0:3, 6:9] = 0.25 * eye * dt * dt  # position
    V[9:12, 12:15] = V[12:15, 15:18] = eye * dt  # biases
    return V @ noise @ V.T


# ----------------------------------------------------------------------------------------------------------
# new files
# ----------------------------------------------------------------------------------------------------------
def test_vins_file_gives_vins_the_continuous_growth(model, nk):
    text = export_text(model, "vins")
    got = vins_reads(cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY))
    cov = vins_step_cov(got["acc_n"], got["acc_w"], got["gyr_n"], got["gyr_w"])
    (na, ka), (ng, kg) = nk["accel"], nk["gyro"]
    # per step: velocity N_a^2 dt, rotation N_g^2 dt, biases K^2 dt -- the continuous model's growth
    assert np.diag(cov)[6:9] == pytest.approx([na**2 * DT] * 3, rel=1e-6)
    assert np.diag(cov)[3:6] == pytest.approx([ng**2 * DT] * 3, rel=1e-6)
    assert np.diag(cov)[9:15] == pytest.approx([ka**2 * DT] * 3 + [kg**2 * DT] * 3, rel=1e-6)
    # the value a Kalibr-style continuous density would have given VINS: half the variance per step, wrong by √2
    assert got["acc_n"] == pytest.approx(na * math.sqrt(2 * F), rel=1e-3)
    assert "DISCRETE per-sample std" in text and "VINS reads DISCRETE" in text and text.startswith("%YAML:1.0")


def test_lio_sam_file_gives_gtsam_the_continuous_growth(model, nk):
    text = export_text(model, "lio-sam")
    got = ros_reads(text, "lio-sam")
    (na, ka), (ng, kg) = nk["accel"], nk["gyro"]
    # GTSAM: velocity += R*dt * (imuAccNoise^2 / dt) * (R*dt)' per sample; bias sigma^2 = imuAccBiasN^2 * dt_ij
    assert (got["imuAccNoise"] ** 2 / DT) * DT**2 == pytest.approx(na**2 * DT, rel=1e-6)  # float32 read
    assert (got["imuGyrNoise"] ** 2 / DT) * DT**2 == pytest.approx(ng**2 * DT, rel=1e-6)
    assert got["imuAccBiasN"] ** 2 * DT == pytest.approx(ka**2 * DT, rel=1e-6)
    assert got["imuGyrBiasN"] ** 2 * DT == pytest.approx(kg**2 * DT, rel=1e-6)
    assert "CONTINUOUS white-noise density" in text and "LIO-SAM reads CONTINUOUS" in text


def test_fast_lio_file_gives_the_ekf_the_continuous_growth(model, nk):
    text = export_text(model, "fast-lio")
    got = ros_reads(text, "fast-lio")
    (na, ka), (ng, kg) = nk["accel"], nk["gyro"]
    # esekfom predict(): P += (dt F_w) Q (dt F_w)', |F_w| = 1 on velocity (rotation), rotation and biases
    assert DT**2 * got["acc_cov"] == pytest.approx(na**2 * DT, rel=1e-6)
    assert DT**2 * got["gyr_cov"] == pytest.approx(ng**2 * DT, rel=1e-6)
    assert DT**2 * got["b_acc_cov"] == pytest.approx(ka**2 * DT, rel=1e-6)
    assert DT**2 * got["b_gyr_cov"] == pytest.approx(kg**2 * DT, rel=1e-6)
    assert "DISCRETE per-sample variance" in text and "FAST-LIO reads DISCRETE" in text


def test_new_formats_carry_the_notes_and_refuse_one_sensor(model, tmp_path, capsys):
    """The same header (per-axis pairs, notes, warnings) as the other formats; a one-sensor model is refused."""
    for fmt in KEYS:
        text = export_text(model, fmt)
        assert "# Per axis (continuous-time, before inflation):" in text and "gyro_z:" in text
    mp = tmp_path / "m.json"
    ImuModel.from_fits({a: model.fit(a) for a in AXES[:3]}).save(mp)
    capsys.readouterr()
    assert main(["export", str(mp), "--to", "fast-lio", "--out", str(tmp_path / "f.yaml")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "needs acc_cov, b_acc_cov" in err and not (tmp_path / "f.yaml").exists()


# ----------------------------------------------------------------------------------------------------------
# --into the tools' stock files
# ----------------------------------------------------------------------------------------------------------
def _others(text: str, keys: tuple[str, ...]) -> list[str]:
    return [ln for ln in text.splitlines(keepends=True) if ln.split(":")[0].strip() not in keys]


@pytest.mark.parametrize("fmt", list(KEYS))
def test_into_the_stock_file_changes_only_the_imu_keys(tmp_path, model, fmt, capsys):
    path = tmp_path / STOCK[fmt]
    shutil.copyfile(FIX / STOCK[fmt], path)
    before = path.read_text()
    mp = model.save(tmp_path / "imu_model.json")
    assert main(["export", str(mp), "--to", fmt, "--into", str(path)]) == 0
    after = path.read_text()
    ours = {k: v for k, v in zip(KEYS[fmt], _expected(model, fmt))}
    got = (vins_reads(cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)) if fmt == "vins" else
           ros_reads(after, fmt))  # fmt: skip
    # exact, except LIO-SAM's nh.param<float> (float32: relative 6e-8)
    assert got == (pytest.approx(ours, rel=1e-7) if fmt == "lio-sam" else ours)
    assert _others(after, KEYS[fmt]) == _others(before, KEYS[fmt])  # every other line, byte for byte, in order
    assert len(after.splitlines()) == len(before.splitlines())  # updated where they stood
    assert (tmp_path / f"{STOCK[fmt]}.bak").read_text() == before
    assert "backup" in capsys.readouterr().err


def _expected(model, fmt):
    """Our numbers for the tool, in KEYS order (written in the shortest text that reads back exactly)."""
    from imunoise.export.vins_lio import tool_values

    a, g = tool_values(sensor_noise(model, "accel"), fmt), tool_values(sensor_noise(model, "gyro"), fmt)
    return [a[0], a[1], g[0], g[1]]


def test_into_lio_sam_adds_a_missing_key_inside_its_block(tmp_path, model):
    path = tmp_path / "params.yaml"
    path.write_text((FIX / STOCK["lio-sam"]).read_text().replace("  imuGyrBiasN: 3.5640318696367613e-05\n", ""))
    assert main(["export", str(model.save(tmp_path / "m.json")), "--to", "lio-sam", "--into", str(path)]) == 0
    data = yaml.safe_load(path.read_text())
    assert data["lio_sam"]["imuGyrBiasN"] == pytest.approx(sensor_noise(model, "gyro").random_walk, rel=1e-3)
    assert "imuGyrBiasN" not in data["navsat"] and data["navsat"]["frequency"] == 50


@pytest.mark.parametrize(("fmt", "fixture", "says"), [
    ("vins", "kalibr_imu.yaml", "not a VINS-Mono / VINS-Fusion config"),
    ("lio-sam", "fast_lio_avia.yaml", "no lio_sam block"),
    ("fast-lio", "lio_sam_params.yaml", "no mapping block"),
])  # fmt: skip
def test_into_refuses_another_tools_file(tmp_path, model, capsys, fmt, fixture, says):
    path = tmp_path / fixture
    shutil.copyfile(FIX / fixture, path)
    before = path.read_bytes()
    mp = model.save(tmp_path / "m.json")
    capsys.readouterr()
    assert main(["export", str(mp), "--to", fmt, "--into", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and says in err and f"--into {path}" in err
    assert path.read_bytes() == before and not list(tmp_path.glob("*.bak*"))


def test_a_topic_for_a_tool_whose_topic_is_not_written_is_refused(tmp_path, model, capsys):
    mp = model.save(tmp_path / "m.json")
    capsys.readouterr()
    assert main(["export", str(mp), "--to", "vins", "--imu-topic", "/imu", "--out", str(tmp_path / "v.yaml")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--imu-topic" in err and "drop --imu-topic" in err
    assert not (tmp_path / "v.yaml").exists()


def test_every_command_offers_every_export_format():
    from imunoise.cli.options import EXPORT_TOOLS
    from imunoise.export.formats import FORMATS

    assert set(EXPORT_TOOLS) == set(FORMATS)
