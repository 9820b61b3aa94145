"""The exported files read as the tools read them (issue 22): OpenVINS and ORB-SLAM3 through ``cv2.FileStorage``
(both use OpenCV's FileStorage), Kalibr through PyYAML, each read reproduced from the tool's source (cited per
read), values equal to ours; ``export --into`` on fixtures with the key structure of the tools' own files.

Sources (commit read in brackets):
- OpenVINS [rpng/open_vins 93adc24]: ov_msckf/src/core/VioManagerOptions.h — print_and_load_noise() l.159-162
  (the four densities), print_and_load_state() l.306-315 (Tw, Ta, R_IMUtoACC, R_IMUtoGYRO, Tg);
  ov_msckf/src/state/StateOptions.h print() (``model``: "kalibr"/"calibrated"/"rpng", else exit);
  ov_msckf/src/ros/ROS1Visualizer.cpp setup_subscribers() (``rostopic``); the parser [14211e2]
  ov_core/src/utils/opencv_yaml_parse.h: parse_external_yaml() opens the chain with cv::FileStorage and needs
  the ``imu0`` node, node_found() scans the node's keys, parse<T>() does ``node[name] >> value`` and
  parse(.., Eigen::Matrix3d&) reads ``node[name][r][c]`` for r, c < 3; any miss -> successful() false ->
  "unable to parse all parameters, please fix".
- ORB-SLAM3 [UZ-SLAMLab/ORB_SLAM3 1464d8f]: src/System.cc System() takes Settings only when ``File.version``
  is the string "1.0", else the legacy readers; src/Settings.cc readParameter<float>() l.36-63 (real, or int
  accepted) and readIMU() (IMU.NoiseGyro, IMU.NoiseAcc, IMU.GyroWalk, IMU.AccWalk, IMU.Frequency as float,
  IMU.T_b_c1 as cv::Mat); legacy src/Tracking.cc ParseIMUParamFile() (Tbc 4x4 mat; IMU.Frequency isInt();
  the four densities isReal()).
- Kalibr [ethz-asl/kalibr]: aslam_offline_calibration/kalibr/python/kalibr_common/ConfigReader.py —
  ParametersBase.readYaml() (yaml.safe_load), ImuParameters.getRosTopic() (a str), getUpdateRate() (> 0),
  getAccelerometerStatistics() / getGyroStatistics() (KeyError -> "Field ... missing", > 0, discrete
  sigma = N / sqrt(1 / update_rate)).
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import cv2
import pytest
import yaml

from imunoise.cli import main
from imunoise.export import export_text, sensor_noise, update_into, write_export
from imunoise.noise.estimator import GMWMFit, gmwm
from imunoise.noise.imu_model import ImuModel
from imunoise.noise.model import Model

F = 200.0
FIX = Path(__file__).resolve().parents[1] / "fixtures"
AXES = ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]
ORB_KEYS = ("IMU.NoiseGyro", "IMU.NoiseAcc", "IMU.GyroWalk", "IMU.AccWalk")
KALIBR_KEYS = ("gyroscope_noise_density", "accelerometer_noise_density", "gyroscope_random_walk",
               "accelerometer_random_walk")  # fmt: skip
INTRINSICS = ("Tw", "Ta", "R_IMUtoACC", "R_IMUtoGYRO", "Tg")


@pytest.fixture(scope="module")
def base_fit() -> GMWMFit:
    x = Model.parse("WN+RW").with_params({"WN.sigma2": 1e-4, "RW.gamma2": 1e-10}).simulate(2**12, seed=3)
    return gmwm("WN+RW", x, freq=F, unit="rad/s", n_random=4, n_local=2)


def _with(fit: GMWMFit, params: dict, unit: str, **extra) -> GMWMFit:
    """A WN+RW fit of data simulated with ``params``: the export gate checks a fit against its own data, so the
    test models are real fits (a fit with its parameters swapped by hand would leave its WV band)."""
    x = Model.parse("WN+RW").with_params(params).simulate(2**12, seed=3)
    d = gmwm("WN+RW", x, freq=F, unit=unit, n_random=4, n_local=2).to_dict()
    d["extra"] = {**(d.get("extra") or {}), **extra}
    return GMWMFit.from_dict(d)


@pytest.fixture(scope="module")
def model(base_fit) -> ImuModel:
    fits = {}
    for i, a in enumerate(AXES):
        s = 1.0 + 0.1 * i
        gyro = a.startswith("gyro")
        p = {"WN.sigma2": (1e-6 if gyro else 4e-4) * s, "RW.gamma2": (1e-12 if gyro else 1e-9) * s}
        fits[a] = _with(base_fit, p, "rad/s" if gyro else "m/s²")
    return ImuModel.from_fits(fits, source={"topic": "/sensors/imu"})


@pytest.fixture(scope="module")
def ours(model) -> dict[str, float]:
    """Our values under both naming schemes."""
    g, a = sensor_noise(model, "gyro"), sensor_noise(model, "accel")
    vals = [g.noise_density, a.noise_density, g.random_walk, a.random_walk]
    return {**dict(zip(ORB_KEYS, vals)), **dict(zip(KALIBR_KEYS, vals))}


# ----------------------------------------------------------------------------------------------------------
# the readers, reproduced
# ----------------------------------------------------------------------------------------------------------
def openvins_reads(path: Path) -> dict:
    """OpenVINS' reads of the IMU chain (module docstring: parse_external("relative_config_imu", "imu0", ...))."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)  # opencv_yaml_parse.h parse_external_yaml()
    assert fs.isOpened()
    assert "imu0" in fs.root().keys()  # parse_external_yaml(): node_found(root, sensor_name) else failure
    imu = fs.getNode("imu0")
    keys = list(imu.keys())
    assert len(keys) == len(set(keys)), f"duplicate keys in imu0: {keys}"  # cv::FileStorage reads the first
    out = {}
    # VioManagerOptions.h l.159-162: sigma_w, sigma_wb, sigma_a, sigma_ab as double (parse<T>: node >> double,
    # which keeps the default on a non-number: require a real so the value is really read)
    for k in KALIBR_KEYS:
        assert k in keys, k  # parse(): node_found() else all_params_found_successfully = false
        assert imu.getNode(k).isReal(), k
        out[k] = imu.getNode(k).real()
    # ROS1Visualizer.cpp setup_subscribers(): parse_external(.., "imu0", "rostopic", topic_imu) as std::string
    assert imu.getNode("rostopic").isString()
    out["rostopic"] = imu.getNode("rostopic").string()
    # StateOptions.h print(): parse_external(.., "imu0", "model", imu_model_str): kalibr|calibrated|rpng
    assert imu.getNode("model").isString() and imu.getNode("model").string() in ("kalibr", "calibrated", "rpng")
    out["model"] = imu.getNode("model").string()
    # VioManagerOptions.h l.306-315 + opencv_yaml_parse.h parse(.., Eigen::Matrix3d&): node[name][r][c]
    for k in INTRINSICS:
        assert k in keys, k
        node = imu.getNode(k)
        assert node.isSeq() and node.size() == 3, k
        out[k] = [[node.at(r).at(c).real() for c in range(3)] for r in range(3)]
        assert all(node.at(r).size() == 3 for r in range(3)), k
    # update_rate: not read by OpenVINS (its rate comes from the messages); Kalibr's chain reader reads it
    out["update_rate"] = imu.getNode("update_rate").real()
    return out


def orbslam3_reads(path: Path) -> dict:
    """ORB-SLAM3 v1.0's reads (System.cc picks Settings or the legacy Tracking reader; module docstring)."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    assert fs.isOpened()
    keys = list(fs.root().keys())
    assert len(keys) == len(set(keys)), "duplicate keys (OpenCV 3.4: 'Duplicated key'; 4.x/5.x: first wins)"
    v = fs.getNode("File.version")
    legacy = not (not v.empty() and v.isString() and v.string() == "1.0")  # System.cc System()
    out = {"legacy": legacy}
    for k in ORB_KEYS:
        node = fs.getNode(k)
        assert not node.empty(), k  # Settings.cc readParameter<float>(): required -> exit(-1)
        # legacy Tracking.cc ParseIMUParamFile(): isReal() else b_miss_params; v1.0 also takes an int
        assert node.isReal() if legacy else (node.isReal() or node.isInt()), k
        out[k] = node.real()
    freq = fs.getNode("IMU.Frequency")
    if legacy:
        assert freq.isInt(), "legacy ParseIMUParamFile(): IMU.Frequency must be an integer"
        out["IMU.Frequency"] = int(freq.real())
        tbc = fs.getNode("Tbc").mat()  # ParseIMUParamFile(): Tbc 4x4 else b_miss_params
    else:
        assert freq.isReal() or freq.isInt()  # readParameter<float>() l.49-56
        out["IMU.Frequency"] = freq.real()
        tbc = fs.getNode("IMU.T_b_c1").mat()  # readIMU(): readParameter<cv::Mat>("IMU.T_b_c1") required
    assert tbc is not None and tbc.shape == (4, 4)
    return out


def kalibr_reads(path: Path) -> dict:
    """Kalibr's ImuParameters reads (ConfigReader.py; module docstring)."""
    data = yaml.safe_load(path.read_text())  # ParametersBase.readYaml()
    assert isinstance(data["rostopic"], str)  # getRosTopic(): checkRosTopic()
    assert data["update_rate"] > 0.0  # getUpdateRate(): checkUpdateRate()
    for k in KALIBR_KEYS:  # getAccelerometerStatistics() / getGyroStatistics(): KeyError -> "Field .. missing"
        assert data[k] > 0.0, k
    data["gyro_discrete"] = data["gyroscope_noise_density"] / math.sqrt(1.0 / data["update_rate"])
    return data


def _copy(tmp_path: Path, name: str) -> Path:
    dst = tmp_path / name
    shutil.copyfile(FIX / name, dst)
    return dst


def _others_unchanged(before: str, after: str, ours: tuple[str, ...]) -> None:
    """Every line that is not one of our keys is there, byte for byte and in order."""
    def keep(lines):
        return [ln for ln in lines if ln.split(":")[0].strip() not in ours]

    assert keep(after.splitlines(keepends=True))[: len(keep(before.splitlines(keepends=True)))] == keep(
        before.splitlines(keepends=True)
    )


# ----------------------------------------------------------------------------------------------------------
# new files
# ----------------------------------------------------------------------------------------------------------
def test_openvins_file_passes_the_v27_reads(tmp_path, model, ours):
    path = write_export(model, "openvins", tmp_path / "kalibr_imu_chain.yaml")
    got = openvins_reads(path)
    assert {k: got[k] for k in KALIBR_KEYS} == {k: ours[k] for k in KALIBR_KEYS}
    assert got["rostopic"] == "/sensors/imu" and got["model"] == "kalibr" and got["update_rate"] == F
    eye = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    assert [got[k] for k in INTRINSICS] == [eye, eye, eye, eye, [[0.0] * 3] * 3]
    text = path.read_text()
    assert "OpenVINS v2.6" in text and ">= v2.7" in text  # which versions read it
    # the same reads on OpenVINS' own euroc_mav chain (the fixture) pass: the harness is not stricter than OpenVINS
    assert openvins_reads(FIX / "openvins_kalibr_imu_chain.yaml")["model"] == "kalibr"


def test_orbslam3_and_kalibr_files_pass_their_reads(tmp_path, model, ours):
    text = export_text(model, "orbslam3")  # the IMU block alone: the IMU reads of Settings::readIMU
    fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    assert [fs.getNode(k).real() for k in ORB_KEYS] == [ours[k] for k in ORB_KEYS]
    assert fs.getNode("IMU.Frequency").isReal() and fs.getNode("IMU.Frequency").real() == F
    mem = cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY
    legacy = cv2.FileStorage(export_text(model, "orbslam3", legacy=True), mem)
    assert legacy.getNode("IMU.Frequency").isInt() and int(legacy.getNode("IMU.Frequency").real()) == 200
    got = kalibr_reads(write_export(model, "kalibr", tmp_path / "imu.yaml"))
    assert {k: got[k] for k in KALIBR_KEYS} == {k: ours[k] for k in KALIBR_KEYS}
    assert got["rostopic"] == "/sensors/imu" and got["update_rate"] == F
    assert got["gyro_discrete"] == pytest.approx(ours["gyroscope_noise_density"] * math.sqrt(F), rel=1e-14)


def test_topic_of_the_data_in_every_export(tmp_path, model, base_fit):
    """The bag topic recorded with the data (model source, or a fit's extra) goes into every file naming one."""
    for fmt in ("kalibr", "openvins", "json"):
        assert "/sensors/imu" in export_text(model, fmt)
        assert "/other" in export_text(model, fmt, topic="/other")  # an explicit topic wins
    fit = _with(base_fit, {"WN.sigma2": 1e-6, "RW.gamma2": 1e-12}, "rad/s", topic="/bag/imu")
    assert "rostopic: /bag/imu  # the IMU ROS topic of the data" in export_text(fit, "kalibr", partial=True)
    bare = ImuModel.from_fits({a: model.fit(a) for a in AXES})
    assert "rostopic: /imu0  # the IMU ROS topic (not recorded with the data" in export_text(bare, "kalibr")


# ----------------------------------------------------------------------------------------------------------
# --into
# ----------------------------------------------------------------------------------------------------------
def test_into_orbslam3_v1_settings(tmp_path, model, ours, capsys):
    path = _copy(tmp_path, "orbslam3_euroc_v1.yaml")
    before = path.read_text()
    assert orbslam3_reads(path)["IMU.NoiseGyro"] == pytest.approx(1.7e-4)  # EuRoC's value before
    model_path = model.save(tmp_path / "imu_model.json")
    assert main(["export", str(model_path), "--to", "orbslam3", "--into", str(path)]) == 0
    got = orbslam3_reads(path)
    assert not got["legacy"] and got["IMU.Frequency"] == F
    assert {k: got[k] for k in ORB_KEYS} == {k: ours[k] for k in ORB_KEYS}
    assert (tmp_path / "orbslam3_euroc_v1.yaml.bak").read_text() == before
    _others_unchanged(before, path.read_text(), (*ORB_KEYS, "IMU.Frequency"))
    assert len(path.read_text().splitlines()) == len(before.splitlines())  # updated where they stood
    assert "backup" in capsys.readouterr().err
    # a second update keeps the first backup and numbers the next one
    assert main(["export", str(model_path), "--to", "orbslam3", "--into", str(path)]) == 0
    assert (tmp_path / "orbslam3_euroc_v1.yaml.bak").read_text() == before
    assert (tmp_path / "orbslam3_euroc_v1.yaml.bak.1").exists()


def test_into_orbslam3_legacy_writes_an_integer_frequency(tmp_path, model, ours):
    path = _copy(tmp_path, "orbslam3_euroc_legacy.yaml")
    before = path.read_text()
    res = update_into(model, "orbslam3", path)
    got = orbslam3_reads(path)
    assert res.legacy and got["legacy"] and got["IMU.Frequency"] == 200
    assert {k: got[k] for k in ORB_KEYS} == {k: ours[k] for k in ORB_KEYS}
    _others_unchanged(before, path.read_text(), (*ORB_KEYS, "IMU.Frequency"))
    # --legacy forces the integer on a v1.0 file too
    v1 = _copy(tmp_path, "orbslam3_euroc_v1.yaml")
    mp = model.save(tmp_path / "m.json")
    assert main(["export", str(mp), "--to", "orbslam3", "--legacy", "--into", str(v1)]) == 0
    fs = cv2.FileStorage(str(v1), cv2.FILE_STORAGE_READ)
    assert fs.getNode("IMU.Frequency").isInt()


def test_into_removes_the_duplicates_of_an_earlier_append(tmp_path, model, ours):
    """The old README flow (`>> settings.yaml`): OpenCV reads the first key, so EuRoC's values won."""
    path = _copy(tmp_path, "orbslam3_euroc_v1.yaml")
    with open(path, "a") as fh:
        fh.write(export_text(model, "orbslam3").replace("%YAML:1.0\n", ""))
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    assert fs.getNode("IMU.NoiseGyro").real() == pytest.approx(1.7e-4)  # the bug: our value ignored
    res = update_into(model, "orbslam3", path)
    assert sorted(res.duplicates_removed) == sorted([*ORB_KEYS, "IMU.Frequency"])
    got = orbslam3_reads(path)  # asserts no duplicate key
    assert {k: got[k] for k in ORB_KEYS} == {k: ours[k] for k in ORB_KEYS}


def test_into_openvins_chains(tmp_path, model, ours):
    v26 = _copy(tmp_path, "openvins_kalibr_imu_chain_v26.yaml")
    before = v26.read_text()
    with pytest.raises(AssertionError):
        openvins_reads(v26)  # a v2.6 chain fails the >= v2.7 reads
    res = update_into(model, "openvins", v26)
    assert res.blocks_added == ("Tw", "R_IMUtoGYRO", "Ta", "R_IMUtoACC", "Tg") and res.appended == ("model",)
    got = openvins_reads(v26)
    assert {k: got[k] for k in KALIBR_KEYS} == {k: ours[k] for k in KALIBR_KEYS}
    assert got["rostopic"] == "/sensors/imu" and got["update_rate"] == F
    _others_unchanged(before, v26.read_text(), (*KALIBR_KEYS, "rostopic", "update_rate"))
    # a calibrated v2.7 chain: its intrinsics are never overwritten
    v27 = _copy(tmp_path, "openvins_kalibr_imu_chain.yaml")
    v27.write_text(v27.read_text().replace("  Tw:\n    - [ 1.0, 0.0, 0.0 ]", "  Tw:\n    - [ 1.002, 0.0, 0.0 ]"))
    update_into(model, "openvins", v27)
    assert openvins_reads(v27)["Tw"][0][0] == 1.002


def test_into_kalibr_keeps_its_layout(tmp_path, model, ours):
    path = _copy(tmp_path, "kalibr_imu.yaml")
    before = path.read_text()
    update_into(model, "kalibr", path, topic="/cam_imu/imu")
    got = kalibr_reads(path)
    assert {k: got[k] for k in KALIBR_KEYS} == {k: ours[k] for k in KALIBR_KEYS}
    assert got["rostopic"] == "/cam_imu/imu" and got["update_rate"] == F
    after = path.read_text()
    _others_unchanged(before, after, (*KALIBR_KEYS, "rostopic", "update_rate"))
    assert "gyroscope_noise_density:     " in after  # the file's alignment after the colon kept


def test_into_keeps_crlf_and_the_files_topic_when_none_is_known(tmp_path, model):
    path = tmp_path / "imu.yaml"
    path.write_bytes((FIX / "kalibr_imu.yaml").read_bytes().replace(b"\n", b"\r\n"))
    bare = ImuModel.from_fits({a: model.fit(a) for a in AXES})  # no topic recorded
    update_into(bare, "kalibr", path)
    raw = path.read_bytes()
    assert raw.count(b"\r\n") == raw.count(b"\n") and kalibr_reads(path)["rostopic"] == "/imu0"


@pytest.mark.parametrize(
    ("fmt", "fixture", "says"),
    [
        ("orbslam3", "kalibr_imu.yaml", "not an ORB-SLAM3 settings file"),
        ("orbslam3", "openvins_kalibr_imu_chain.yaml", "not an ORB-SLAM3 settings file"),
        ("openvins", "orbslam3_euroc_v1.yaml", "no imu0 block"),
        ("kalibr", "openvins_kalibr_imu_chain.yaml", "Kalibr's PyYAML reader refuses"),
        ("kalibr", "orbslam3_euroc_legacy.yaml", "not a Kalibr imu.yaml"),
    ],
)
def test_into_refuses_a_file_of_another_tool(tmp_path, model, capsys, fmt, fixture, says):
    path = _copy(tmp_path, fixture)
    before = path.read_bytes()
    mp = model.save(tmp_path / "imu_model.json")
    capsys.readouterr()
    assert main(["export", str(mp), "--to", fmt, "--into", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and says in err and f"--into {path}" in err
    assert path.read_bytes() == before and not list(tmp_path.glob("*.bak*"))


def test_into_refuses_what_it_cannot_edit_in_place(tmp_path, model):
    from imunoise.errors import DataError

    flow = tmp_path / "flow.yaml"
    flow.write_text("%YAML:1.0\nimu0: {rostopic: /imu0, update_rate: 200.0}\n")
    with pytest.raises(DataError, match="flow style"):
        update_into(model, "openvins", flow)
    tabs = tmp_path / "tabs.yaml"
    tabs.write_text("imu0:\n\trostopic: /imu0\n")
    with pytest.raises(DataError, match="tabs"):
        update_into(model, "openvins", tabs)
    with pytest.raises(DataError, match="no such file; to write a new file use --out"):
        update_into(model, "kalibr", tmp_path / "missing.yaml")
    assert not list(tmp_path.glob("*.bak*"))


def test_one_sensor_model_never_writes_a_rejected_file(tmp_path, base_fit, capsys):
    fit = _with(base_fit, {"WN.sigma2": 1e-6, "RW.gamma2": 1e-12}, "rad/s", column="gyro_z")
    mp = tmp_path / "model.json"
    fit.save(str(mp))
    keys = {"kalibr": "accelerometer_noise_density, accelerometer_random_walk",
            "openvins": "accelerometer_noise_density, accelerometer_random_walk",
            "orbslam3": "IMU.NoiseAcc, IMU.AccWalk"}  # fmt: skip
    for fmt, missing in keys.items():
        capsys.readouterr()
        assert main(["export", str(mp), "--to", fmt, "--out", str(tmp_path / f"{fmt}.yaml")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"needs {missing}" in err and "--sensor gyro" in err
        assert not (tmp_path / f"{fmt}.yaml").exists()
    assert main(["export", str(mp), "--to", "kalibr", "--sensor", "gyro", "--out", str(tmp_path / "g.yaml")]) == 0
    assert "SENSOR BLOCK ONLY (gyro)" in (tmp_path / "g.yaml").read_text()
    assert main(["export", str(mp), "--to", "json", "--out", str(tmp_path / "g.json")]) == 0
    # --into a file that has the accelerometer keys: a complete file, gyro keys ours
    k = _copy(tmp_path, "kalibr_imu.yaml")
    assert main(["export", str(mp), "--to", "kalibr", "--into", str(k)]) == 0
    got = kalibr_reads(k)
    assert got["gyroscope_noise_density"] == sensor_noise(fit, "gyro").noise_density
    assert got["accelerometer_noise_density"] == 1.86e-03
    # ... into one without them: refused, nothing written
    bare = tmp_path / "bare.yaml"
    bare.write_text("rostopic: /imu0\nupdate_rate: 200.0\n")
    capsys.readouterr()
    assert main(["export", str(mp), "--to", "kalibr", "--into", str(bare)]) == 2
    err = capsys.readouterr().err
    assert "the model has no value for accelerometer_noise_density, accelerometer_random_walk" in err
    assert bare.read_text() == "rostopic: /imu0\nupdate_rate: 200.0\n" and not (tmp_path / "bare.yaml.bak").exists()


def test_into_orbslam3_needs_the_files_own_transform(tmp_path, model, capsys):
    path = tmp_path / "s.yaml"
    text = (FIX / "orbslam3_euroc_v1.yaml").read_text()
    path.write_text(text.replace("IMU.T_b_c1:", "IMU.T_x:"))
    capsys.readouterr()
    assert main(["export", str(model.save(tmp_path / "m.json")), "--to", "orbslam3", "--into", str(path)]) == 2
    err = capsys.readouterr().err
    assert "would miss IMU.T_b_c1" in err and "the file must hold IMU.T_b_c1 itself" in err and err.count("\n") == 1


def test_fit_export_of_one_axis(tmp_path, capsys):
    """`fit --export` on one gyro axis: refused (exit 2, the missing keys named) unless --sensor asks for the block."""
    import numpy as np

    x = Model.parse("WN").with_params({"WN.sigma2": 1e-6}).simulate(4096, seed=5)
    csv = tmp_path / "g.csv"
    np.savetxt(csv, x[:, None], header="gyro_z", comments="", delimiter=",")
    base = ["fit", str(csv), "--column", "gyro_z", "--freq", "200", "--units", "rad/s", "--model", "WN+RW"]
    capsys.readouterr()
    assert main([*base, "--export", "kalibr", "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "need both sensors' keys; add --sensor gyro|accel" in err
    assert not (tmp_path / "a" / "imu.yaml").exists() and not (tmp_path / "a" / "model.json").exists()
    assert main([*base, "--sensor", "gyro", "--export", "kalibr", "--out", str(tmp_path / "b")]) == 0
    assert yaml.safe_load((tmp_path / "b" / "imu.yaml").read_text())["gyroscope_noise_density"] > 0


def test_into_follows_a_symlink_and_keeps_the_mode(tmp_path, model):
    real = _copy(tmp_path, "kalibr_imu.yaml")
    real.chmod(0o640)
    link = tmp_path / "imu_link.yaml"
    link.symlink_to(real)
    update_into(model, "kalibr", link)
    assert link.is_symlink() and kalibr_reads(link)["rostopic"] == "/sensors/imu"
    assert real.stat().st_mode & 0o777 == 0o640 and (tmp_path / "kalibr_imu.yaml.bak").exists()


# The README's export block (the README quotes it; the docs keep both the same), run as written: the three
# settings files stand for the user's own (the fixtures, copied to the paths the block names).
README_EXPORT_BLOCK = """\
imunoise export out/calib/imu_model.json --force --to orbslam3 --into my_rig/EuRoC.yaml     # IMU.NoiseGyro ...
imunoise export out/calib/imu_model.json --force --to openvins --into my_rig/kalibr_imu_chain.yaml
imunoise export out/calib/imu_model.json --force --to kalibr --into my_rig/imu.yaml
"""


def test_readme_export_block_runs_as_written(tmp_path, model, ours, monkeypatch):
    import shlex

    (tmp_path / "out" / "calib").mkdir(parents=True)
    model.save(tmp_path / "out" / "calib" / "imu_model.json")
    (tmp_path / "my_rig").mkdir()
    for src, dst in (("orbslam3_euroc_v1.yaml", "EuRoC.yaml"), ("openvins_kalibr_imu_chain.yaml",
                     "kalibr_imu_chain.yaml"), ("kalibr_imu.yaml", "imu.yaml")):  # fmt: skip
        shutil.copyfile(FIX / src, tmp_path / "my_rig" / dst)
    monkeypatch.chdir(tmp_path)
    for line in README_EXPORT_BLOCK.splitlines():  # each command as the shell would split it (comments dropped)
        argv = shlex.split(line, comments=True)
        assert argv[0] == "imunoise" and main(argv[1:]) == 0, line
    rig = tmp_path / "my_rig"
    assert {k: orbslam3_reads(rig / "EuRoC.yaml")[k] for k in ORB_KEYS} == {k: ours[k] for k in ORB_KEYS}
    chain = openvins_reads(rig / "kalibr_imu_chain.yaml")
    assert chain["gyroscope_noise_density"] == ours["gyroscope_noise_density"]
    assert kalibr_reads(rig / "imu.yaml")["accelerometer_random_walk"] == ours["accelerometer_random_walk"]
    assert sorted(p.name for p in rig.glob("*.bak")) == ["EuRoC.yaml.bak", "imu.yaml.bak",
                                                                "kalibr_imu_chain.yaml.bak"]
