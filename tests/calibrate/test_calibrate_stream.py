"""`imunoise calibrate` on logs streamed block by block (:func:`imunoise.calibrate.stream_stops`): the same
stops, pooled wavelet variance and model as the whole-log path run forward only (``both_ways=False``), on
simulated drives written to a CSV and to a bag (with the GNSS speed check); against the default whole-log
path (both ways) the same stops with later ends."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from imunoise.calibrate import ImuLog, calibrate, detect_stops, read_log, stream_stops
from imunoise.cli import main
from imunoise.cli.options import parse_units
from imunoise.imu import AXES
from imunoise.sim import DriveConfig, simulate_drive

COLUMNS = "gyro_x=gx,gyro_y=gy,gyro_z=gz,accel_x=ax,accel_y=ay,accel_z=az"
UNITS = "gyro=rad/s,accel=m/s^2"
CFG = DriveConfig(duration_s=300.0, n_stops=3, stop_range_s=(20.0, 40.0), static_s=40.0)


@pytest.fixture(scope="module")
def drive():
    return simulate_drive(CFG, "WN+RW", seed=11)


def write_csv(path, imu, a=0, b=None):
    g, acc = imu.rates()
    sl = slice(a, b)
    np.savetxt(path, np.column_stack([imu.t[sl], g[sl], acc[sl]]), delimiter=",", fmt="%.17g",
               header="t,gx,gy,gz,ax,ay,az", comments="")
    return path


def test_streamed_csv_equals_whole_log(drive, tmp_path):
    path = write_csv(tmp_path / "drive.csv", drive.imu)
    src = {"columns": COLUMNS, "units": parse_units(UNITS), "time_column": "t"}
    whole = detect_stops(read_log(path, **src), both_ways=False)
    streamed = stream_stops(path, **src)
    assert streamed.lambda0 == whole.lambda0 and streamed.lambda0_source == whole.lambda0_source
    assert len(whole.stops) >= 3 and streamed.stops == whole.stops
    assert streamed.detection.segments == whole.detection.segments and streamed.dropped == whole.dropped
    assert streamed.log.duration_s == pytest.approx(whole.log.duration_s, abs=1e-9)
    assert streamed.log.rate_hz == pytest.approx(whole.log.rate_hz, rel=1e-12)
    for k in range(len(AXES)):
        for x, y in zip(whole.stop_samples(k), streamed.stop_samples(k), strict=True):
            np.testing.assert_array_equal(x, y)
    # the report's series is per second, not per sample
    assert streamed.detection.t.size == pytest.approx(whole.log.duration_s, abs=2)
    a, b = calibrate([whole], complete="WN+RW"), calibrate([streamed], complete="WN+RW")
    for ax in AXES:
        wa, wb = a.fits[ax].wv, b.fits[ax].wv
        np.testing.assert_allclose(wb.variance, wa.variance, rtol=1e-9, atol=0)
        assert str(b.fits[ax].model) == str(a.fits[ax].model)
        assert b.axes[ax].N == pytest.approx(a.axes[ax].N, rel=1e-9)
        assert b.axes[ax].K == pytest.approx(a.axes[ax].K, rel=1e-9)


@pytest.mark.slow
def test_streamed_bag_with_gnss_equals_whole_log_cli(drive, tmp_path, capsys):
    from imunoise.io.navinput import write_nav_bag

    bag = write_nav_bag(tmp_path / "drive.bag", drive.imu, drive.gnss, week=CFG.gps_week)
    outs = {}
    for mode in ("whole", "stream"):
        out = tmp_path / mode
        extra = ["--stream"] if mode == "stream" else []
        code = main(["calibrate", str(bag), "--gnss", str(bag), "--complete", "WN+RW", "--out", str(out), *extra])
        assert code == 0, capsys.readouterr().err
        outs[mode] = out
    assert "(streamed)" in capsys.readouterr().err
    cw, cs = (json.loads((outs[m] / "calibration.json").read_text()) for m in ("whole", "stream"))
    # the whole log is detected both ways, the stream forward with its end trim: the same stops, each
    # streamed one starting with the whole-log one and ending no earlier (the reversed pass ends before the
    # departure, the trim only by its measured lag)
    sw, ss = cw["logs"][0]["stops"], cs["logs"][0]["stops"]
    assert len(ss) == len(sw) and cs["n_stops"] >= 3
    for a, b in zip(sw, ss, strict=True):
        assert b["t0"] == a["t0"] and a["t1"] <= b["t1"] <= a["t1"] + 2.0, (a, b)
    assert cw["logs"][0]["lambda0_m_s2"] == cs["logs"][0]["lambda0_m_s2"]
    for ax in AXES:
        assert cs["axes"][ax]["N"] == pytest.approx(cw["axes"][ax]["N"], rel=0.02)
    assert (outs["stream"] / "report.html").exists()


def test_threshold_streams_and_no_stop_gives_the_same_message(drive, tmp_path, capsys):
    still = drive.static_mask
    a = int(np.flatnonzero(~still)[0]) + 200
    b = a + int(np.flatnonzero(still[a:])[0]) - 200
    path = write_csv(tmp_path / "moving.csv", drive.imu, a, b)
    base = ["calibrate", str(path), "--columns", COLUMNS, "--units", UNITS, "--time-column", "t"]
    for lam, why in (([], "s of stops pooled"), (["--lambda0", "1e-6"], "no usable stop")):
        msgs = []
        for extra in ([], ["--stream-above", "1000"]):
            code = main([*base, *lam, "--out", str(tmp_path / f"out{len(msgs)}"), *extra])
            err = capsys.readouterr().err.strip().splitlines()
            assert code == 2
            msgs.append(err[-1])
            if extra:
                assert any("streaming" in line for line in err), err
        # the same message; the seconds differ (both ways against forward with the end trim)
        assert re.sub(r"\d+\.\d+", "#", msgs[0]) == re.sub(r"\d+\.\d+", "#", msgs[1]) and why in msgs[0], msgs


def test_stream_refuses_what_it_cannot_read(tmp_path, drive):
    from imunoise.io.kfgins import write_imu

    path = write_imu(tmp_path / "imu.txt", drive.imu)
    assert main(["calibrate", str(path), "--stream", "--out", str(tmp_path / "o")]) == 2
    assert isinstance(read_log(path), ImuLog)
