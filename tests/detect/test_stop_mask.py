"""The drive's stops are detected in one place (imunoise.detect.stop_mask): the in-use moving flag and the ZUPT
mask of ``nav --zupt`` are the masks of the rule each computed on its own before, and ``nav --zupt
--imu-model`` with an in-motion part runs the detector once over the whole drive."""

from __future__ import annotations

import json

import numpy as np
import pytest

import imunoise.detect
import imunoise.detect.detector
import imunoise.detect.stop_mask
import imunoise.nav.ekf
from imunoise.cli import main
from imunoise.cli.nav import drive_stops, zupt_mask
from imunoise.detect import DetectorConfig, detect_static, learn_lambda0
from imunoise.inuse.stops import moving_flag
from imunoise.nav.zupt_policy import ZUPT_AFTER, ZUPT_EVERY, zupt_due
from imunoise.noise.model import Model
from imunoise.noise.processes import RW, WN
from imunoise.sim.drive import DriveConfig, simulate_drive

STATIC_S = 30.0


@pytest.fixture(scope="module")
def drive():
    cfg = DriveConfig(duration_s=240.0, n_stops=2, static_s=35.0, gnss_rate_hz=5.0, seed=5)
    return simulate_drive(cfg, "mems", seed=5)


def _previous_moving_flag(imu, static_duration):
    """inuse.stops.moving_flag before the stops were detected in one place."""
    gyro, accel = imu.rates()
    t = np.asarray(imu.t, dtype=float)
    lam = learn_lambda0(accel[t < t[0] + static_duration])
    return ~np.asarray(detect_static(t, accel, gyro, DetectorConfig(lambda0=lam)).static, dtype=bool)


def _previous_zupt_mask(imu, static_duration):
    """cli.nav.zupt_mask before the stops were detected in one place."""
    gyro, accel = imu.rates()
    lam = learn_lambda0(accel[imu.t < imu.t[0] + static_duration])
    det = detect_static(imu.t, accel, gyro, DetectorConfig(lambda0=lam))
    return zupt_due(det.static, every=ZUPT_EVERY, after=ZUPT_AFTER)


def test_moving_flag_and_zupt_mask_are_the_previous_masks(drive):
    imu = drive.imu
    moving = moving_flag(imu, STATIC_S)
    zupt = zupt_mask(drive_stops(imu, STATIC_S))
    np.testing.assert_array_equal(moving, _previous_moving_flag(imu, STATIC_S))
    np.testing.assert_array_equal(zupt, _previous_zupt_mask(imu, STATIC_S))
    # a drive with stops and driving: the masks are not trivially all one value
    assert 0.1 < moving.mean() < 0.95 and zupt.any()
    assert not np.any(zupt & moving)  # a ZUPT is only due at a stop


def _entry(white: float, rw: float, unit: str) -> dict:
    return {**Model([WN(sigma2=white), RW(gamma2=rw)]).to_dict(), "freq_hz": 100.0, "unit": unit}


def test_nav_zupt_with_an_in_motion_part_detects_once(drive, tmp_path, monkeypatch):
    data = drive.write(tmp_path / "sim")
    model = {"gyro": _entry(1e-7, 1e-14, "rad/s"), "accel": _entry(1e-4, 1e-10, "m/s^2"),
             "in_motion": {"axes": {a: {"white_factor": {"value": 3.0, "ci95": [2.0, 4.0]},
                                        "bias": {"model": "gm", "sigma": 5.8e-4, "tau_s": 60.0, "ci95": {}}}
                                    for a in ("gyro_x", "gyro_y", "gyro_z")}, "bounds": {}, "evidence": {}}}
    path = tmp_path / "model.json"
    path.write_text(json.dumps(model))

    calls = []
    real_detect = imunoise.detect.detector.detect_static

    def counting_detect(t, *a, **k):
        calls.append(len(t))
        return real_detect(t, *a, **k)

    for module in (imunoise.detect, imunoise.detect.detector, imunoise.detect.stop_mask):
        monkeypatch.setattr(module, "detect_static", counting_detect)
    runs = []
    real_run = imunoise.nav.ekf.run_ekf

    def recording_run(*a, **k):
        runs.append(k)
        return real_run(*a, **k)

    monkeypatch.setattr(imunoise.nav.ekf, "run_ekf", recording_run)
    out = tmp_path / "nav"
    assert main(["nav", "--data", str(data), "--zupt", "--imu-model", str(path), "--static-duration",
                 str(STATIC_S), "--no-plots", "--out", str(out)]) == 0
    assert calls == [drive.imu.t.size]  # one detection, over the whole drive
    assert len(runs) == 1 and json.loads((out / "metrics.json").read_text())["in_motion"] is True
    # both masks the filter got are the ones the two separate detections gave before
    monkeypatch.setattr(imunoise.detect, "detect_static", real_detect)
    np.testing.assert_array_equal(runs[0]["moving"], _previous_moving_flag(drive.imu, STATIC_S))
    np.testing.assert_array_equal(runs[0]["zupt"], _previous_zupt_mask(drive.imu, STATIC_S))
