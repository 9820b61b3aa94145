"""Test helper (not a test module): an export read back as its tool reads it, and the continuous-time (N, K) the
tool then carries.

The reads are the ones reproduced, with the tools' sources and lines, in tests/export/test_export_clients.py
(Kalibr, OpenVINS, ORB-SLAM3) and tests/export/test_export_vins_lio.py (VINS, LIO-SAM, FAST-LIO); the (N, K) of
VINS, LIO-SAM and FAST-LIO is the per-sample covariance growth of the tool's own propagation over dt, as those
tests replay it (N²·dt for the white noise, K²·dt for the bias random walk).
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
from test_export_clients import KALIBR_KEYS, ORB_KEYS, kalibr_reads, openvins_reads
from test_export_vins_lio import KEYS, ros_reads, vins_reads, vins_step_cov

NOISE_KEYS = {"kalibr": KALIBR_KEYS, "openvins": KALIBR_KEYS, "orbslam3": ORB_KEYS, **KEYS}
"""The four noise keys each tool reads (Kalibr order: N gyro, N accel, K gyro, K accel; VINS-style: acc_n,
acc_w, gyr_n, gyr_w)."""


def tool_reads(fmt: str, path: Path) -> dict[str, float]:
    """The four noise keys of the ``fmt`` file at ``path`` as the tool reads them."""
    if fmt == "kalibr":
        got = kalibr_reads(path)
    elif fmt == "openvins":
        got = openvins_reads(path)
    elif fmt in ("orbslam3", "vins"):
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)  # both read with cv::FileStorage
        if fmt == "vins":
            got = vins_reads(fs)
        else:  # Settings.cc readParameter<float>(): a real (the file's transforms are the camera's, not ours)
            assert all(fs.getNode(k).isReal() for k in ORB_KEYS)
            got = {k: fs.getNode(k).real() for k in ORB_KEYS}
    else:
        got = ros_reads(path.read_text(), fmt)
    return {k: got[k] for k in NOISE_KEYS[fmt]}


def carried_nk(fmt: str, got: dict[str, float], freq: float) -> dict[str, tuple[float, float]]:
    """Per sensor the continuous (N, K) the tool carries with the keys ``got`` (:func:`tool_reads`) at the IMU
    rate ``freq`` [Hz]."""
    if fmt in ("kalibr", "openvins", "orbslam3"):  # continuous densities, read as they stand
        ng, na, kg, ka = (got[k] for k in NOISE_KEYS[fmt])
    elif fmt == "vins":  # midPointIntegration()'s V*noise*V' over one step: rotation, velocity, biases
        dt = 1.0 / freq
        cov = vins_step_cov(got["acc_n"], got["acc_w"], got["gyr_n"], got["gyr_w"], dt)
        ng, na, ka, kg = (math.sqrt(cov[i, i] / dt) for i in (3, 6, 9, 12))
    elif fmt == "lio-sam":  # GTSAM: (imuAccNoise²/dt)·dt² per sample; bias σ² = imuAccBiasN²·dt
        na, ka, ng, kg = (got[k] for k in KEYS[fmt])
    else:  # esekfom predict(): (dt)²·acc_cov per sample
        na, ka, ng, kg = (math.sqrt(got[k] / freq) for k in KEYS[fmt])
    return {"gyro": (ng, kg), "accel": (na, ka)}
