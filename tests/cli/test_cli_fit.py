"""`imunoise fit` on CSV columns and ROS bags: legacy single-axis behaviour, multi-axis model files,
units invariance (issue 6 acceptance 2), bag formats giving one model (acceptance 1, small N)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from imunoise.cli import main
from imunoise.export import read_export, sensor_noise
from imunoise.io.rosbag import write_imu_bag
from imunoise.noise.estimator import gmwm
from imunoise.noise.imu_model import ImuModel
from imunoise.noise.model import Model
from imunoise.units import G0

F = 200.0
N_G, K_G = 2e-3, 4e-5  # rad/s/√Hz, rad/s²/√Hz
N_A, K_A = 3e-2, 8e-4  # m/s²/√Hz, m/s³/√Hz


def _imu(n: int, seed: int = 0) -> np.ndarray:
    """(n, 6) WN+RW per axis with the continuous values above (docs/guide/theory.rst, 'Latent processes': σ² = N²f, γ² =
    K²/f)."""
    cols = []
    for i in range(6):
        N, K = (N_G, K_G) if i < 3 else (N_A, K_A)
        m = Model.parse("WN+RW").with_params({"WN.sigma2": N * N * F, "RW.gamma2": K * K / F})
        cols.append(m.simulate(n, seed=seed + i))
    return np.column_stack(cols)


def test_single_column_legacy_behaviour(tmp_path):
    x = _imu(4096)[:, 0]
    p = tmp_path / "g.csv"
    np.savetxt(p, np.column_stack([np.arange(x.size), np.degrees(x)]), delimiter=",", header="k,gx", comments="")
    out = tmp_path / "fit"
    assert main(["fit", str(p), "--freq", "200", "--column", "gx", "--units", "deg/s", "--model", "WN+RW",
                 "--out", str(out)]) == 0  # fmt: skip
    d = json.loads((out / "model.json").read_text())
    ref = gmwm("WN+RW", np.loadtxt(p, delimiter=",", skiprows=1)[:, 1] * math.pi / 180, freq=F, unit="rad/s")
    assert d["model"] == "WN + RW" and d["unit"] == "rad/s" and d["extra"]["column"] == "gx"
    assert d["extra"]["source_unit"] == "deg/s" and (out / "wv.png").exists()
    assert d["params"] == pytest.approx(ref.params, rel=1e-9)
    assert main(["fit", str(p), "--freq", "200", "--model", "WN"]) == 2  # two columns: which one?
    assert main(["fit", str(p), "--model", "WN"]) == 2  # no rate


def test_csv_units_and_time_column_give_the_same_model(tmp_path, capsys):
    """Acceptance 2: deg/s and g give the same model as rad/s and m/s² (automatic selection)."""
    x = _imu(2**14, seed=10)[:, [0, 3]]
    t_ns = 1_600_000_000_000_000_000 + np.arange(x.shape[0], dtype=np.int64) * 5_000_000
    si, other = tmp_path / "si.csv", tmp_path / "deg_g.csv"
    with open(si, "w") as a, open(other, "w") as b:
        a.write("t,wx,fx\n")
        b.write("t,wx,fx\n")
        for k in range(x.shape[0]):
            a.write(f"{t_ns[k]},{float(x[k, 0])!r},{float(x[k, 1])!r}\n")
            b.write(f"{t_ns[k]},{float(np.degrees(x[k, 0]))!r},{float(x[k, 1] / G0)!r}\n")
    models = []
    for path, units in ((si, "gyro=rad/s,accel=m/s2"), (other, "gyro=deg/s,accel=g")):
        out = tmp_path / path.stem
        args = ["fit", str(path), "--columns", "gyro_x=wx,accel_x=fx", "--units", units, "--time-column", "t",
                "--time-unit", "ns", "--auto", "--out", str(out)]  # fmt: skip
        assert main(args) == 0
        models.append(ImuModel.load(out / "imu_model.json"))
    printed = capsys.readouterr().out
    assert "continuous" in printed and "discrete" in printed
    a, b = models
    assert a.freq_hz == b.freq_hz == F
    for axis in ("gyro_x", "accel_x"):
        assert a.axes[axis]["model"] == b.axes[axis]["model"]
        assert a.axes[axis]["params"] == pytest.approx(b.axes[axis]["params"], rel=1e-6)
        assert a.axes[axis]["unit"] == b.axes[axis]["unit"]
    assert main(["fit", str(si), "--columns", "wx", "--time-column", "t", "--time-unit", "ns", "--freq", "100",
                 "--model", "WN"]) == 2  # fmt: skip


@pytest.mark.slow
def test_three_bag_formats_give_one_model_and_a_kalibr_file(tmp_path):
    """Acceptance 1 in small: the same samples in .bag, .db3 and .mcap give the same model and export."""
    n = 2**15
    x = _imu(n, seed=20)
    stamps = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 5_000_000
    results = []
    for name in ("r1.bag", "r2.db3", "r3.mcap"):
        path = write_imu_bag(tmp_path / name, stamps, x[:, :3], x[:, 3:], topic="/imu0")
        out = tmp_path / f"fit_{name.replace('.', '_')}"
        assert main(["fit", str(path), "--columns", "gyro_x,accel_x", "--auto", "--export", "kalibr",
                     "--out", str(out)]) == 0  # fmt: skip
        results.append((ImuModel.load(out / "imu_model.json"), read_export(out / "imu.yaml")))
    (m0, k0), *rest = results
    for m, k in rest:
        assert {a: d["params"] for a, d in m.axes.items()} == {a: d["params"] for a, d in m0.axes.items()}
        assert k == k0
    assert k0["rostopic"] == "/imu0" and k0["update_rate"] == F
    assert k0["gyroscope_noise_density"] == sensor_noise(m0, "gyro").noise_density
    assert k0["gyroscope_noise_density"] == pytest.approx(N_G, rel=0.03)
    assert k0["accelerometer_noise_density"] == pytest.approx(N_A, rel=0.03)


def test_bag_single_axis_topic_and_errors(tmp_path, capsys):
    x = _imu(4096, seed=30)
    path = write_imu_bag(tmp_path / "b.mcap", np.arange(4096) * 5_000_000, x[:, :3], x[:, 3:], topic="/imu/raw")
    out = tmp_path / "gz"
    # a gyro-only ORB-SLAM3 file is one the tool rejects: refused before anything is written...
    assert main(["fit", str(path), "--column", "gyro_z", "--model", "WN", "--export", "orbslam3",
                 "--out", str(out)]) == 2  # fmt: skip
    assert not (out / "orbslam3_imu.yaml").exists()
    # ...unless the sensor block alone is asked for
    assert main(["fit", str(path), "--column", "gyro_z", "--model", "WN", "--export", "orbslam3",
                 "--sensor", "gyro", "--out", str(out)]) == 0  # fmt: skip
    d = json.loads((out / "model.json").read_text())
    assert d["extra"]["topic"] == "/imu/raw" and d["unit"] == "rad/s" and d["freq_hz"] == F
    assert "IMU.NoiseGyro" in read_export(out / "orbslam3_imu.yaml")
    capsys.readouterr()
    assert main(["fit", str(path), "--topic", "/imu", "--model", "WN"]) == 2
    assert "/imu/raw [sensor_msgs/msg/Imu, 4096 messages]" in capsys.readouterr().err
    assert main(["fit", str(path), "--column", "gyro_z", "--model", "WN", "--freq", "100"]) == 2
    assert main(["fit", str(path), "--model", "WN", "--decimate", "2", "--decimate-method", "drop"]) == 2
    out2 = tmp_path / "avg"
    assert main(["fit", str(path), "--column", "gyro_z", "--model", "WN", "--decimate", "4", "--out", str(out2)]) == 0
    d2 = json.loads((out2 / "model.json").read_text())
    assert d2["freq_hz"] == F / 4  # block average: the density is kept
    assert d2["continuous"]["WN.noise_density"] == pytest.approx(d["continuous"]["WN.noise_density"], rel=0.06)
