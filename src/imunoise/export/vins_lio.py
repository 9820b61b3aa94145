"""The IMU noise keys of VINS-Mono / VINS-Fusion, LIO-SAM and FAST-LIO (:mod:`imunoise.export`).

Each tool reads its four numbers under its own convention, found in its source (cited per tool below and in
``docs/guide/exports.rst``; the reads are reproduced in ``tests/export/test_export_vins_lio.py``). From the
continuous-time pair (N, K) of :func:`imunoise.export.sensor_noise` and the IMU rate f = 1/dt:

- **VINS** (``acc_n``, ``gyr_n``, ``acc_w``, ``gyr_w``; ``cv::FileStorage`` in ``readParameters``):
  DISCRETE per-sample standard deviations. ``integration_base.h`` puts acc_n² on each of the two samples a
  mid-point step averages, each with weight dt/2 on the velocity (``V.block(6,0)``, ``V.block(6,6)``): the step
  adds 0.5·acc_n²·dt², and the bias rows (``V.block(9,12) = I·dt``) add acc_w²·dt². A white noise of density N
  adds N²·dt per step and a random walk K adds K²·dt, so acc_n = N·√(2f) [m/s²] and acc_w = K·√f [m/s³]
  (gyro alike in rad/s, rad/s²).
- **LIO-SAM** (``imuAccNoise``, ``imuGyrNoise``, ``imuAccBiasN``, ``imuGyrBiasN``; ROS params under
  ``lio_sam/``): CONTINUOUS densities. ``imuPreintegration.cpp`` sets GTSAM's ``accelerometerCovariance`` to
  imuAccNoise² ("acc white noise in continuous"; GTSAM divides it by dt per sample) and the bias between-factor
  sigma to √(Δt_ij)·imuAccBiasN: imuAccNoise = N [m/s²/√Hz], imuAccBiasN = K [m/s³/√Hz].
- **FAST-LIO** (``acc_cov``, ``gyr_cov``, ``b_acc_cov``, ``b_gyr_cov``; ROS params under ``mapping/``):
  DISCRETE per-sample VARIANCES of the rates. ``IMU_Processing.hpp`` puts them on the diagonal of Q and the
  IKFoM ``esekfom.hpp`` predict() adds (dt·F_w)·Q·(dt·F_w)ᵀ per IMU sample, so the velocity gains acc_cov·dt² and
  the bias b_acc_cov·dt² per step: acc_cov = N²·f [(m/s²)²], b_acc_cov = K²·f [(m/s³)²].

The discrete values hold at the rate they were computed for (written beside them); a tool fed at another rate
needs them again (``imunoise export`` on the model, with the data at that rate).
"""

from __future__ import annotations

import math

from imunoise.errors import ModelError
from imunoise.export.in_use import InUseNoise, in_use_comment
from imunoise.export.noise import BASE_UNIT, SensorNoise, density_units, format_float

__all__ = ["TOOL_FORMATS", "TOOL_FILENAMES", "TOOL_KEYS", "TOOL_BLOCK", "tool_values", "tool_comment",
           "tool_text", "CONVENTION"]

TOOL_FORMATS = ("vins", "lio-sam", "fast-lio")
TOOL_FILENAMES = {"vins": "vins_imu.yaml", "lio-sam": "lio_sam_imu.yaml", "fast-lio": "fast_lio_imu.yaml"}
# (white-noise key, random-walk key) per sensor, in the order each tool's stock file writes them
TOOL_KEYS = {
    "vins": {"accel": ("acc_n", "acc_w"), "gyro": ("gyr_n", "gyr_w")},
    "lio-sam": {"accel": ("imuAccNoise", "imuAccBiasN"), "gyro": ("imuGyrNoise", "imuGyrBiasN")},
    "fast-lio": {"accel": ("acc_cov", "b_acc_cov"), "gyro": ("gyr_cov", "b_gyr_cov")},
}
# the map the keys live in: VINS top level (cv::FileStorage root), LIO-SAM nh.param("lio_sam/..."),
# FAST-LIO nh.param("mapping/...")
TOOL_BLOCK: dict[str, str | None] = {"vins": None, "lio-sam": "lio_sam", "fast-lio": "mapping"}
CONVENTION = {
    "vins": "VINS reads DISCRETE per-sample standard deviations (vins_estimator/src/factor/integration_base.h: "
    "noise = acc_n^2 on each sample of a mid-point step, V = 0.5*R*dt -> 0.5*acc_n^2*dt^2 per step; bias rows "
    "V = I*dt -> acc_w^2*dt^2): acc_n = N*sqrt(2f), acc_w = K*sqrt(f) so that a step adds N^2*dt and K^2*dt.",
    "lio-sam": "LIO-SAM reads CONTINUOUS densities (src/imuPreintegration.cpp: GTSAM accelerometerCovariance = "
    "imuAccNoise^2, 'acc white noise in continuous'; bias BetweenFactor sigma = sqrt(dt_ij)*imuAccBiasN): "
    "imuAccNoise = N, imuAccBiasN = K.",
    "fast-lio": "FAST-LIO reads DISCRETE per-sample VARIANCES (src/IMU_Processing.hpp: Q.diagonal() = acc_cov; "
    "include/IKFoM_toolkit/esekfom/esekfom.hpp predict(): P += (dt*F_w) Q (dt*F_w)^T per IMU sample): "
    "acc_cov = N^2*f, b_acc_cov = K^2*f so that a step adds N^2*dt and K^2*dt.",
}


def tool_values(sn: SensorNoise, fmt: str) -> tuple[float, float]:
    """The (white-noise, random-walk) numbers ``fmt``'s tool reads for one sensor (module docstring).

    Parameters
    ----------
    sn : SensorNoise
        The sensor's continuous-time pair (N, K) and its rate f [Hz].
    fmt : {"vins", "lio-sam", "fast-lio"}
        The tool.

    Returns
    -------
    (float, float)
        VINS (N·√(2f), K·√f); LIO-SAM (N, K); FAST-LIO (N²·f, K²·f).
    """
    n, k, f = sn.noise_density, sn.random_walk, sn.freq_hz
    if fmt == "vins":
        return n * math.sqrt(2.0 * f), k * math.sqrt(f)
    if fmt == "lio-sam":
        return n, k
    if fmt == "fast-lio":
        return n * n * f, k * k * f
    raise ModelError(f"not a VINS/LIO-SAM/FAST-LIO format: {fmt!r}; use vins, lio-sam or fast-lio")


def _units(sensor: str, fmt: str) -> tuple[str, str]:
    base = BASE_UNIT[sensor]
    rate = "rad/s^2" if sensor == "gyro" else "m/s^3"
    if fmt == "lio-sam":
        return density_units(sensor)
    if fmt == "vins":
        return base, rate
    return f"({base})^2", f"({rate})^2"


def tool_comment(sn: SensorNoise, fmt: str, which: str) -> str:
    """The comment beside one written number: its unit, discrete or continuous, and how it follows from (N, K)
    (with the axes it combines and a visible ``--inflate`` factor, as the other formats say them)."""
    n_unit, k_unit = density_units(sn.sensor)
    wn_unit, rw_unit = _units(sn.sensor, fmt)
    f = f"{sn.freq_hz:g} Hz"
    static = tool_values(sn.in_use.static, fmt) if isinstance(sn, InUseNoise) and sn.in_use else (None, None)
    how_axes = f"{sn.combine} over {','.join(a.axis for a in sn.axes)}"
    if which == "N":
        how = {"vins": f"DISCRETE per-sample std = N*sqrt(2f) at f = {f}",
               "lio-sam": "CONTINUOUS white-noise density N",
               "fast-lio": f"DISCRETE per-sample variance = N^2*f at f = {f}"}[fmt]
        val = "" if fmt == "lio-sam" else f"; N = {format_float(sn.noise_density)} {n_unit}"
        infl = f" x {sn.inflate_white:g} (--inflate white)" if sn.inflate_white != 1.0 else ""
        return f"[{wn_unit}] {how}{val} ({how_axes}{infl}){in_use_comment(sn, 'N', static[0])}"
    how = {"vins": f"DISCRETE bias-rate std per sample = K*sqrt(f) at f = {f}",
           "lio-sam": "CONTINUOUS bias random-walk density K",
           "fast-lio": f"DISCRETE bias-rate variance per sample = K^2*f at f = {f}"}[fmt]
    val = "" if fmt == "lio-sam" else f"; K = {format_float(sn.random_walk)} {k_unit}"
    infl = f" x {sn.inflate_rw:g} (--inflate rw)" if sn.inflate_rw != 1.0 else ""
    return f"[{rw_unit}] {how}{val} ({how_axes}{infl}){in_use_comment(sn, 'K', static[1])}"


def tool_text(fmt: str, sensors: dict[str, SensorNoise], header: list[str]) -> str:
    """The file of ``fmt`` for ``sensors``: the header comment lines (the notes every export carries), the
    tool's convention, and the four keys (one sensor's two with ``--sensor``) where the tool reads them.

    Parameters
    ----------
    fmt : {"vins", "lio-sam", "fast-lio"}
        The tool.
    sensors : dict
        ``{"gyro": SensorNoise, "accel": SensorNoise}`` (one of them for a sensor block).
    header : list of str
        Comment lines put first (after ``%YAML:1.0`` for VINS).

    Returns
    -------
    str
    """
    block = TOOL_BLOCK[fmt]
    lines = ["%YAML:1.0"] if fmt == "vins" else []
    lines += header + [f"# {CONVENTION[fmt]}"]
    if fmt == "vins":
        lines.append("# An IMU block: merge it into the VINS config with imunoise export --to vins --into CONFIG.yaml")
    else:
        lines.append(f"# ROS parameters under {block}/: load this file after the tool's own (rosparam load "
                     "overrides these keys only) or merge it with imunoise export --into")
    lines.append("")
    indent = ""
    if block:
        lines.append(f"{block}:")
        indent = "  " if fmt == "lio-sam" else "    "  # the stock files' indentation
    for s in ("accel", "gyro"):
        if s not in sensors:
            continue
        nk, kk = TOOL_KEYS[fmt][s]
        nv, kv = tool_values(sensors[s], fmt)
        lines.append(f"{indent}{nk}: {format_float(nv)}  # {tool_comment(sensors[s], fmt, 'N')}")
        lines.append(f"{indent}{kk}: {format_float(kv)}  # {tool_comment(sensors[s], fmt, 'K')}")
    return "\n".join(lines) + "\n"
