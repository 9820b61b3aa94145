"""Real noise, known truth (imunoise.sim.replay, ``--imu-noise``): a static recording replayed as a drive's IMU
errors — SI conversion, whole-file mean removed, one non-overlapping stretch per drive, the denial
experiment's static part unused by any drive, another rate refused. Synthetic recordings for the mechanics;
the shared ADIS16405 logs (skipped without ../shared) for the real file."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imunoise.cli import main as cli_main
from imunoise.errors import DataError, ModelError
from imunoise.sim import DriveConfig, simulate_drive
from imunoise.sim.replay import G0, load_recording, static_part, stretch

COLS = np.array(["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"])
UNITS = np.array(["deg/s"] * 3 + ["g"] * 3)


def _write(path, data, rate=100.0, cols=COLS, units=UNITS):
    np.savez(path, data=data, columns=cols, units=units, freq_hz=np.float64(rate))
    return str(path)


def _recording(tmp_path, n=70_000, rate=100.0, name="rec.npz"):
    rng = np.random.default_rng(0)
    data = rng.normal(0.0, 0.1, (n, 6)) + np.array([0.5, -0.2, 0.1, 0.01, -0.02, -1.0])
    return _write(tmp_path / name, data, rate), data


def _drive(path, seed, **kw):
    cfg = DriveConfig(seed=seed, duration_s=150.0, n_stops=1, stop_range_s=(5.0, 10.0), static_s=20.0,
                      imu_noise=path, **kw)
    return simulate_drive(cfg, None, seed=seed)


def _errors(d):
    g, a = d.imu.rates()
    gt, at = d.imu_true.rates()
    bias = np.concatenate([d.truth["turn_on_bias"]["gyro_rad_s"], d.truth["turn_on_bias"]["accel_m_s2"]])
    return np.column_stack([g - gt, a - at]) - bias


def test_recording_is_si_with_the_whole_file_mean_removed(tmp_path):
    path, data = _recording(tmp_path)
    rec = load_recording(path)
    scale = np.array([math.pi / 180] * 3 + [G0] * 3)
    np.testing.assert_allclose(rec.errors, (data - data.mean(axis=0)) * scale, rtol=0, atol=1e-12)
    np.testing.assert_allclose(rec.mean_removed, data.mean(axis=0) * scale, rtol=1e-12)


def test_each_drive_replays_its_own_stretch_and_stops_show_the_recording(tmp_path):
    path, _ = _recording(tmp_path)
    rec = load_recording(path)
    d0, d1 = _drive(path, 5, imu_noise_first=5), _drive(path, 6, imu_noise_first=5)
    n = len(d0.imu.t)
    assert d0.truth["imu_noise"]["stretch_samples"] == [0, n] and d1.truth["imu_noise"]["stretch_samples"] == [n, 2 * n]
    np.testing.assert_allclose(_errors(d0), rec.errors[:n], rtol=1e-8, atol=1e-9)  # rates = Δ/Δt with t ≈ 1e5 s
    np.testing.assert_allclose(_errors(d1), rec.errors[n:2 * n], rtol=1e-8, atol=1e-9)  # rates = Δ/Δt with t ≈ 1e5 s
    stop = d1.static_mask
    np.testing.assert_allclose(_errors(d1)[stop], rec.errors[n:2 * n][stop], rtol=1e-8, atol=1e-9)
    assert d0.imu_models == {} and d0.moving_models == {}  # no true model: the recording is the truth
    assert not d0.vibration.any()


def test_no_drive_reaches_the_static_part_and_other_rates_are_refused(tmp_path):
    path, _ = _recording(tmp_path)
    rec = load_recording(path)
    n = 10_001
    assert stretch(rec, 4, n, 100.0, reserve_s=100.0) == (40_004, 50_005)
    with pytest.raises(ModelError, match=r"5 drive\(s\) of 100 s fit"):
        stretch(rec, 5, n, 100.0, reserve_s=100.0)
    assert static_part(rec, 100.0, 100.0).shape == (10_000, 6)
    np.testing.assert_array_equal(static_part(rec, 100.0, 100.0), rec.errors[-10_000:])
    slow, _ = _recording(tmp_path, rate=50.0, name="slow.npz")
    with pytest.raises(ModelError, match="recorded at 50 Hz, the simulator runs at 100 Hz.*not resampled"):
        _drive(slow, 0)
    with pytest.raises(ModelError, match="additive terms only"):
        DriveConfig(imu_noise=path, motion_noise="drive0708")


def test_bad_recordings_name_the_key(tmp_path):
    rng = np.random.default_rng(1)
    with pytest.raises(DataError, match="'units'"):
        load_recording(_write(tmp_path / "u.npz", rng.normal(size=(100, 6)), units=np.array(["g"] * 6)))
    with pytest.raises(DataError, match="'columns'"):
        load_recording(_write(tmp_path / "c.npz", rng.normal(size=(100, 6)), cols=np.array(["a"] * 6)))
    np.savez(tmp_path / "m.npz", data=rng.normal(size=(100, 6)))
    with pytest.raises(DataError, match="'columns' missing"):
        load_recording(str(tmp_path / "m.npz"))


def test_cli_refuses_oracle_and_real_data_with_imu_noise(tmp_path, capsys):
    path, _ = _recording(tmp_path)
    rc = cli_main(["experiment", "online", "--sim", "--imu-noise", path, "--methods", "plain,oracle",
                   "--out", str(tmp_path / "o")])
    assert rc == 2 and "oracle" in capsys.readouterr().err
    rc = cli_main(["experiment", "online", "--imu-noise", path, "--out", str(tmp_path / "r")])
    assert rc == 2 and "--sim" in capsys.readouterr().err


def test_the_shared_adis16405_logs_replay(shared_data):
    f = shared_data("imudata_adis16405", "adis16405_unit1.npz")
    rec = load_recording(str(f))
    assert rec.rate_hz == 100.0 and rec.n == 1_000_000
    assert np.abs(rec.errors.mean(axis=0)).max() < 1e-10  # float sums of 10⁶ values of ≈ 10 m/s²
    assert abs(rec.mean_removed[5] + G0) < 0.3  # z accelerometer reads about −1 g on the bench
    # a 600 s drive: 16 non-overlapping drives, 10 when the last hour is the denial experiment's static part
    n = 60_001
    assert stretch(rec, 15, n, 100.0)[1] <= rec.n
    assert stretch(rec, 9, n, 100.0, reserve_s=3600.0)[1] <= rec.n - 360_000
    with pytest.raises(ModelError, match=r"10 drive\(s\) of 600 s fit"):
        stretch(rec, 10, n, 100.0, reserve_s=3600.0)


def test_denial_fits_the_shared_static_part_once(tmp_path, monkeypatch):
    """Every seed of a replayed denial run shares the recording's end as its static part: fitted once, on exactly
    those samples (the mean of the part removed), and reused."""
    from imunoise.experiments import denial

    path, data = _recording(tmp_path)
    rec = load_recording(str(tmp_path / "rec.npz"))
    calls = []

    def fake(segments, freq, *, complete=None):
        calls.append(segments[0])
        return {"n": segments[0].shape[0]}

    monkeypatch.setattr(denial, "static_models", fake)
    monkeypatch.setattr(denial, "_REPLAY_MODELS", {})
    a = denial._replay_models(rec.path, 200.0, 100.0, None)
    b = denial._replay_models(rec.path, 200.0, 100.0, None)
    assert a is b and len(calls) == 1 and a["n"] == 20_000
    want = rec.errors[-20_000:] - rec.errors[-20_000:].mean(axis=0)
    np.testing.assert_allclose(calls[0], want, rtol=0, atol=1e-15)
    denial._replay_models(rec.path, 100.0, 100.0, None)  # another static length: another fit
    assert len(calls) == 2 and calls[1].shape[0] == 10_000
