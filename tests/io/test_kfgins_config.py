"""The KF-GINS configuration writer (imunoise.io.kfgins_config): the YAML it writes, read back as KF-GINS reads
it, gives the SI values it was given. No KF-GINS binary is needed.

KF-GINS (i2Nav-WHU/KF-GINS, ``src/kf_gins.cpp`` at commit 079e59c, ``loadConfig`` and ``main``) reads every
key with yaml-cpp as ``config["initpos"].as<std::vector<double>>()`` … ``config["imunoise"]["corrtime"]
.as<double>()``, ``config["imudatalen"].as<int>()``, ``config["imudatarate"].as<int>()``,
``config["starttime"].as<double>()``, and converts:

    options.initstate.pos[i]   = vec1[i] * D2R;      options.initstate.pos[2] *= R2D;
    options.initstate.vel[i]   = vec2[i];            options.initstate.euler[i] = vec3[i] * D2R;
    options.initstate.imuerror.gyrbias[i]  = vec1[i] * D2R / 3600.0;
    options.initstate.imuerror.accbias[i]  = vec2[i] * 1e-5;
    options.initstate_std.pos[i] = vec1[i];  options.initstate_std.vel[i] = vec2[i];
    options.initstate_std.euler[i] = vec3[i] * D2R;
    options.initstate_std.imuerror.gyrbias[i] = vec1[i] * D2R / 3600.0;   (initbgstd)
    options.initstate_std.imuerror.accbias[i] = vec2[i] * 1e-5;           (initbastd)
    options.imunoise.gyr_arw *= (D2R / 60.0);  options.imunoise.acc_vrw /= 60.0;
    options.imunoise.gyrbias_std *= (D2R / 3600.0);  options.imunoise.accbias_std *= 1e-5;
    options.imunoise.gyrscale_std *= 1e-6;  options.imunoise.accscale_std *= 1e-6;
    options.imunoise.corr_time *= 3600;
    options.antlever = Eigen::Vector3d(vec1.data());

The same conversions are applied here to what PyYAML reads; yaml-cpp's ``as<double>`` reads the decimal
text the same way (a round-trip ``repr``), and ``as<int>`` needs an integer literal.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from imunoise.errors import DataError
from imunoise.io.kfgins_config import KfginsNoise, kfgins_config, kfgins_yaml, write_kfgins_config

D2R = math.pi / 180.0
R2D = 180.0 / math.pi

SI = {
    "llh": (0.6998181580317266, -1.8351691633152707, 1601.4690449702705),
    "vel_ned": (0.0123, -4.5e-6, 1e-9),
    "euler": (-0.020340814613208, -0.000660184027, -0.115789920000001),
    "gyro_bias": (3.4544e-4, -1.15849e-3, -2.97783e-3),
    "accel_bias": (1e-7, -0.0123, 0.25),
    "sigma_pos0": (0.05, 0.05, 0.1),
    "sigma_vel0": (0.05, 0.02, 0.05),
    "sigma_att0": (0.5 * D2R, 0.5 * D2R, 3.0 * D2R),
    "lever_arm": (0.0, -0.05, 1.25e-3),
}
NOISE = KfginsNoise(
    gyro_arw=0.3 * D2R / 60.0,
    accel_vrw=0.07 / 60.0,
    gyro_bias_std=37.0 * D2R / 3600.0,
    accel_bias_std=1234.5e-5,
    gyro_scale_std=2.5e-3,
    accel_scale_std=1e-4,
    corr_time_s=1800.0,
    init_gyro_bias_std=50.0 * D2R / 3600.0,
    init_accel_bias_std=2500e-5,
)


def _config(**kw):
    args = dict(imu_path="drive/imu.txt", gnss_path="drive/gnss.txt", output_dir="out dir/kf", start_s=243263.0,
                imu_rate_hz=100.00004, noise=NOISE, end_s=-1.0, **SI)
    args.update(kw)
    return kfgins_config(**args)


def _read_as_kfgins(text: str) -> dict:
    """PyYAML's reading with KF-GINS' loadConfig conversions (module docstring)."""
    c = yaml.safe_load(text)
    v = {k: np.array(c[k], dtype=float) for k in c if isinstance(c[k], list)}
    n = {k: np.array(x, dtype=float) if isinstance(x, list) else x for k, x in c["imunoise"].items()}
    pos = v["initpos"] * D2R
    pos[2] *= R2D
    return {
        "raw": c,
        "llh": pos,
        "vel_ned": v["initvel"],
        "euler": v["initatt"] * D2R,
        "gyro_bias": v["initgyrbias"] * D2R / 3600.0,
        "accel_bias": v["initaccbias"] * 1e-5,
        "sigma_pos0": v["initposstd"],
        "sigma_vel0": v["initvelstd"],
        "sigma_att0": v["initattstd"] * D2R,
        "lever_arm": v["antlever"],
        "init_gyro_bias_std": v["initbgstd"] * D2R / 3600.0,
        "init_accel_bias_std": v["initbastd"] * 1e-5,
        "gyro_arw": n["arw"] * (D2R / 60.0),
        "accel_vrw": n["vrw"] / 60.0,
        "gyro_bias_std": n["gbstd"] * (D2R / 3600.0),
        "accel_bias_std": n["abstd"] * 1e-5,
        "gyro_scale_std": n["gsstd"] * 1e-6,
        "accel_scale_std": n["asstd"] * 1e-6,
        "corr_time_s": n["corrtime"] * 3600,
    }


def test_values_read_back_as_kfgins_reads_them_are_the_si_values():
    got = _read_as_kfgins(kfgins_yaml(_config()))
    for key, want in SI.items():
        np.testing.assert_allclose(got[key], want, rtol=4e-16, atol=0, err_msg=key)
    for key in ("gyro_arw", "accel_vrw", "gyro_bias_std", "accel_bias_std", "gyro_scale_std", "accel_scale_std",
                "init_gyro_bias_std", "init_accel_bias_std"):
        np.testing.assert_allclose(got[key], [getattr(NOISE, key)] * 3, rtol=4e-16, atol=0, err_msg=key)
    assert got["corr_time_s"] == NOISE.corr_time_s
    raw = got["raw"]
    # the scalars KF-GINS reads with as<int> / as<double> / as<std::string>
    assert (raw["imudatalen"], raw["imudatarate"]) == (7, 100)
    assert type(raw["imudatalen"]) is int and type(raw["imudatarate"]) is int
    assert (raw["starttime"], raw["endtime"]) == (243263.0, -1.0) and type(raw["starttime"]) is float
    assert (raw["imupath"], raw["gnsspath"], raw["outputpath"]) == ("drive/imu.txt", "drive/gnss.txt", "out dir/kf")
    assert raw["initgyrscale"] == raw["initaccscale"] == [0.0, 0.0, 0.0]


def test_every_number_is_written_exactly_and_read_as_a_float():
    cfg = _config()
    raw = yaml.safe_load(kfgins_yaml(cfg))

    def walk(a, b, where):
        if isinstance(a, dict):
            assert set(a) == set(b), where
            for k in a:
                walk(a[k], b[k], f"{where}.{k}")
        elif isinstance(a, list):
            assert len(a) == len(b) == 3, where
            for x, y in zip(a, b, strict=True):
                assert type(y) is float and x == y, (where, x, y)  # the same double, not a string
        else:
            assert a == b and type(a) is type(b), (where, a, b)

    walk(cfg, raw, "")


def test_exponent_floats_carry_a_point_so_yaml_1_1_reads_numbers():
    text = kfgins_yaml({"a": [1e-05, 2.5e-07, 1e22], "b": 3e-300})
    assert "1.0e-05" in text and "1.0e+22" in text and "3.0e-300" in text
    assert yaml.safe_load(text) == {"a": [1e-05, 2.5e-07, 1e22], "b": 3e-300}


def test_default_noise_is_the_reference_run_of_the_shared_drive():
    n = yaml.safe_load(kfgins_yaml(_config(noise=None)))
    assert n["imunoise"] == {"arw": [0.5] * 3, "vrw": [0.5] * 3, "gbstd": [100.0] * 3, "abstd": [5000.0] * 3,
                             "gsstd": [3000.0] * 3, "asstd": [3000.0] * 3, "corrtime": 1.0}
    assert n["initbgstd"] == [100.0] * 3 and n["initbastd"] == [5000.0] * 3  # KF-GINS' own fallback values


def test_write_is_the_text(tmp_path):
    cfg = _config()
    path = write_kfgins_config(tmp_path / "kf-gins.yaml", cfg)
    assert path.read_text() == kfgins_yaml(cfg)
    assert [p.name for p in tmp_path.iterdir()] == ["kf-gins.yaml"]


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"imu_path": "d/imu.txt.gz"},
         "KF-GINS configuration: d/imu.txt.gz is gzip; KF-GINS reads plain text, decompress it first"),
        ({"imu_rate_hz": 99.5}, "KF-GINS configuration: IMU rate 99.5 Hz is not close to an integer > 0"),
        ({"llh": (0.7, math.nan, 10.0)}, "KF-GINS configuration: llh needs 3 finite values, got [0.7, nan, 10.0]"),
        ({"lever_arm": (0.0, 1.0)}, "KF-GINS configuration: lever_arm needs 3 finite values, got [0.0, 1.0]"),
    ],
)
def test_refused_inputs_name_the_value_and_the_fix(kw, message):
    with pytest.raises(DataError) as exc:
        _config(**kw)
    assert str(exc.value) == message
