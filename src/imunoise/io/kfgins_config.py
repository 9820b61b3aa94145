"""The configuration file of KF-GINS (i2Nav-WHU, C++), written from SI values, to run the C++ reference on
the same data and the same initial state as ``imunoise nav`` (docs/guide/theory.rst, 'Interfaces';
benchmarks/bench_cli.py).

KF-GINS reads one YAML file (its ``config/kf-gins.yaml``) with yaml-cpp, in its own units: degrees for
latitude, longitude and attitude, °/h and mGal for the biases, ppm for the scale factors, °/√h and m/s/√h
for the random walks, hours for the correlation time. :func:`kfgins_config` converts SI values into those
keys and units (the inverse of KF-GINS' ``loadConfig``: ``initpos`` [deg, deg, m], ``initgyrbias`` [°/h] =
rad/s · 180/π · 3600, ``imunoise.arw`` [°/√h] = rad/s/√Hz · 180/π · 60, ``imunoise.vrw`` [m/s/√h] =
m/s²/√Hz · 60, ``corrtime`` [h] = s / 3600); :func:`kfgins_yaml` writes them so that both yaml-cpp and a
YAML 1.1 reader (PyYAML) read every number back as the same double: floats always carry a decimal point
(``1.0e-05``, not ``1e-05``, which YAML 1.1 reads as a string) and 17 significant digits at most
(``repr``), integers where KF-GINS asks for ``int`` (``imudatalen``, ``imudatarate``).

KF-GINS itself is not part of imunoise (GPL-3, C++): build it from its own repository.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from imunoise.errors import DataError
from imunoise.io.atomic import atomic_write_text

__all__ = ["KfginsNoise", "kfgins_config", "kfgins_yaml", "write_kfgins_config"]

_DEG = math.pi / 180.0
_DEG_PER_H = _DEG / 3600.0  # °/h → rad/s
_ARW = _DEG / 60.0  # °/√h → rad/s/√Hz
_VRW = 1.0 / 60.0  # m/s/√h → m/s²/√Hz
_MGAL = 1e-5  # mGal → m/s²
_PPM = 1e-6


@dataclass(frozen=True)
class KfginsNoise:
    """KF-GINS' IMU noise settings in SI units (one value for the three axes of a sensor).

    Defaults: the KF-GINS reference run on the shared drive (data README): ARW 0.5 °/√h, VRW 0.5 m/s/√h,
    gyro bias σ 100 °/h, accel bias σ 5000 mGal, scale σ 3000 ppm, correlation time 1 h; the initial σ of
    the biases and scale factors are these σ (KF-GINS' fallback when ``initbgstd`` … are absent) unless
    ``init_*`` are given.
    """

    gyro_arw: float = 0.5 * _ARW  # rad/s/√Hz
    accel_vrw: float = 0.5 * _VRW  # m/s²/√Hz
    gyro_bias_std: float = 100.0 * _DEG_PER_H  # rad/s
    accel_bias_std: float = 5000.0 * _MGAL  # m/s²
    gyro_scale_std: float = 3000.0 * _PPM
    accel_scale_std: float = 3000.0 * _PPM
    corr_time_s: float = 3600.0
    init_gyro_bias_std: float | None = None  # rad/s; None: gyro_bias_std
    init_accel_bias_std: float | None = None  # m/s²; None: accel_bias_std


def _vec3(x: Sequence[float], name: str, scale: float = 1.0) -> list[float]:
    v = [float(a) for a in x]
    if len(v) != 3 or not all(math.isfinite(a) for a in v):
        raise DataError(f"KF-GINS configuration: {name} needs 3 finite values, got {list(x)!r}")
    return [a * scale for a in v]


def kfgins_config(
    *,
    imu_path: str | Path,
    gnss_path: str | Path,
    output_dir: str | Path,
    start_s: float,
    imu_rate_hz: float,
    llh: Sequence[float],
    vel_ned: Sequence[float],
    euler: Sequence[float],
    lever_arm: Sequence[float],
    gyro_bias: Sequence[float] = (0.0, 0.0, 0.0),
    accel_bias: Sequence[float] = (0.0, 0.0, 0.0),
    sigma_pos0: Sequence[float] = (0.05, 0.05, 0.05),
    sigma_vel0: Sequence[float] = (0.05, 0.05, 0.05),
    sigma_att0: Sequence[float] = (0.5 * _DEG, 0.5 * _DEG, 3.0 * _DEG),
    noise: KfginsNoise | None = None,
    end_s: float = -1.0,
) -> dict:
    """The KF-GINS configuration (keys and units of its ``config/kf-gins.yaml``) from SI values.

    Parameters
    ----------
    imu_path, gnss_path : str or Path
        Uncompressed KF-GINS text files (KF-GINS reads plain text only; a ``.gz`` is refused).
    output_dir : str or Path
        Existing folder for KF_GINS_Navresult.nav, KF_GINS_IMU_ERR.txt and KF_GINS_STD.txt.
    start_s, end_s : float
        Processing interval [s of week]; ``end_s`` −1: to the end of the IMU file.
    imu_rate_hz : float
        IMU rate (KF-GINS asks for an integer; it uses 1/rate only where a time step is ≥ 0.1 s).
    llh, vel_ned, euler : sequence of float
        Initial IMU-point latitude, longitude [rad], height [m]; velocity NED [m/s]; roll, pitch, yaw [rad].
    lever_arm : sequence of float
        GNSS antenna from the IMU in the body frame (FRD) [m].
    gyro_bias, accel_bias : sequence of float
        Initial bias estimates [rad/s], [m/s²].
    sigma_pos0, sigma_vel0, sigma_att0 : sequence of float
        Initial σ: position N, E, D [m], velocity [m/s], roll, pitch, yaw [rad].
    noise : KfginsNoise, optional
        IMU noise settings (default :class:`KfginsNoise`).

    Returns
    -------
    dict
        KF-GINS keys in its units (plain floats and ints), ready for :func:`kfgins_yaml`.

    Raises
    ------
    DataError
        For a gzip input, a non-integer rate or a non-finite value.
    """
    n = noise or KfginsNoise()
    for p in (imu_path, gnss_path):
        if str(p).endswith(".gz"):
            raise DataError(f"KF-GINS configuration: {p} is gzip; KF-GINS reads plain text, decompress it first")
    rate = round(float(imu_rate_hz))
    if not math.isfinite(imu_rate_hz) or rate <= 0 or abs(rate - imu_rate_hz) > 1e-3 * rate:
        raise DataError(f"KF-GINS configuration: IMU rate {imu_rate_hz!r} Hz is not close to an integer > 0")
    if not (math.isfinite(start_s) and math.isfinite(end_s)):
        raise DataError(f"KF-GINS configuration: start {start_s!r} / end {end_s!r} must be finite")
    lat, lon, h = _vec3(llh, "llh")
    gbs = n.gyro_bias_std if n.init_gyro_bias_std is None else n.init_gyro_bias_std
    abs_ = n.accel_bias_std if n.init_accel_bias_std is None else n.init_accel_bias_std
    return {
        "imupath": str(imu_path),
        "gnsspath": str(gnss_path),
        "outputpath": str(output_dir),
        "imudatalen": 7,
        "imudatarate": int(rate),
        "starttime": float(start_s),
        "endtime": float(end_s),
        "initpos": [lat / _DEG, lon / _DEG, h],
        "initvel": _vec3(vel_ned, "vel_ned"),
        "initatt": _vec3(euler, "euler", 1.0 / _DEG),
        "initgyrbias": _vec3(gyro_bias, "gyro_bias", 1.0 / _DEG_PER_H),
        "initaccbias": _vec3(accel_bias, "accel_bias", 1.0 / _MGAL),
        "initgyrscale": [0.0, 0.0, 0.0],
        "initaccscale": [0.0, 0.0, 0.0],
        "initposstd": _vec3(sigma_pos0, "sigma_pos0"),
        "initvelstd": _vec3(sigma_vel0, "sigma_vel0"),
        "initattstd": _vec3(sigma_att0, "sigma_att0", 1.0 / _DEG),
        "initbgstd": _vec3([gbs] * 3, "init gyro bias σ", 1.0 / _DEG_PER_H),
        "initbastd": _vec3([abs_] * 3, "init accel bias σ", 1.0 / _MGAL),
        "imunoise": {
            "arw": _vec3([n.gyro_arw] * 3, "arw", 1.0 / _ARW),
            "vrw": _vec3([n.accel_vrw] * 3, "vrw", 1.0 / _VRW),
            "gbstd": _vec3([n.gyro_bias_std] * 3, "gbstd", 1.0 / _DEG_PER_H),
            "abstd": _vec3([n.accel_bias_std] * 3, "abstd", 1.0 / _MGAL),
            "gsstd": _vec3([n.gyro_scale_std] * 3, "gsstd", 1.0 / _PPM),
            "asstd": _vec3([n.accel_scale_std] * 3, "asstd", 1.0 / _PPM),
            "corrtime": n.corr_time_s / 3600.0,
        },
        "antlever": _vec3(lever_arm, "lever_arm"),
    }


def _scalar(x: object) -> str:
    if isinstance(x, bool):
        raise DataError(f"KF-GINS configuration: unexpected boolean {x!r}")
    if isinstance(x, int):
        return str(x)
    if isinstance(x, float):
        if not math.isfinite(x):
            raise DataError(f"KF-GINS configuration: non-finite value {x!r}")
        r = repr(x)  # shortest text that reads back as the same double
        mant, e, exp = r.partition("e")
        if "." not in mant:
            mant += ".0"  # YAML 1.1 floats need the point: 1e-05 would be read as a string
        return mant + e + exp
    return json.dumps(str(x))  # a JSON string is a YAML double-quoted scalar


def kfgins_yaml(cfg: dict) -> str:
    """YAML text of :func:`kfgins_config`'s dict (block mappings, flow lists; module docstring)."""

    def lines(d: dict, indent: str) -> list[str]:
        out = []
        for k, v in d.items():
            if isinstance(v, dict):
                out += [f"{indent}{k}:", *lines(v, indent + "  ")]
            elif isinstance(v, list):
                out.append(f"{indent}{k}: [{', '.join(_scalar(a) for a in v)}]")
            else:
                out.append(f"{indent}{k}: {_scalar(v)}")
        return out

    head = "# KF-GINS configuration written by imunoise (imunoise.io.kfgins_config); KF-GINS units\n"
    return head + "\n".join(lines(cfg, "")) + "\n"


def write_kfgins_config(path: str | Path, cfg: dict) -> Path:
    """Write :func:`kfgins_yaml` of ``cfg`` to ``path`` (atomically) and return the path."""
    return atomic_write_text(path, kfgins_yaml(cfg))
