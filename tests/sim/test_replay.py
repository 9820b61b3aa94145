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
from imunoise.sim.replay import G0, check_vehicles, drive_samples, load_recording, static_part, stretch, stretch_index

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


def test_vehicle_stretches_are_disjoint_oldest_first_and_k1_is_the_drive_layout():
    # vehicle v of K drives: stretch v·K + j, j = 0 the oldest drive, K − 1 the scored one (k = 0 before it)
    assert [stretch_index(v, 0, 1) for v in range(4)] == [0, 1, 2, 3]  # K = 1: the single-drive layout
    got = {(v, k): stretch_index(v, k, 3) for v in range(5) for k in range(3)}
    assert sorted(got.values()) == list(range(15))  # every stretch once: no two drives of any vehicles share one
    assert [got[(1, k)] for k in (2, 1, 0)] == [3, 4, 5]  # oldest first, the scored drive last
    with pytest.raises(ModelError, match="needs --vehicle-drives 3 or more"):
        stretch_index(0, 2, 2)


def test_each_drive_of_a_vehicle_replays_its_own_stretch(tmp_path):
    """Two vehicles of two drives on a synthetic recording: the four drives replay the four disjoint stretches
    the layout gives (exactly those samples), and a drive's stretch depends on its seed alone (the same drive
    simulated again, or with other seeds in the run, replays the same samples)."""
    path, _ = _recording(tmp_path)
    rec = load_recording(path)
    off = 7_000_000  # an earlier drive is another seed; the shifted first seed names the same vehicle
    drives = {}
    for v in (0, 1):
        drives[(v, 0)] = _drive(path, 5 + v, imu_noise_first=5, imu_noise_drives=2)
        drives[(v, 1)] = _drive(path, 5 + v + off, imu_noise_first=5 + off, imu_noise_drives=2, imu_noise_earlier=1)
    n = len(drives[(0, 0)].imu.t)
    assert n == drive_samples(150.0, 100.0)
    spans = {key: d.truth["imu_noise"]["stretch_samples"] for key, d in drives.items()}
    assert spans == {(0, 1): [0, n], (0, 0): [n, 2 * n], (1, 1): [2 * n, 3 * n], (1, 0): [3 * n, 4 * n]}
    for (v, k), d in drives.items():
        a, b = spans[(v, k)]
        np.testing.assert_allclose(_errors(d), rec.errors[a:b], rtol=1e-8, atol=1e-9)
    again = _drive(path, 6 + off, imu_noise_first=5 + off, imu_noise_drives=2, imu_noise_earlier=1)
    np.testing.assert_array_equal(again.imu.dtheta, drives[(1, 1)].imu.dtheta)
    np.testing.assert_array_equal(again.imu.dv, drives[(1, 1)].imu.dv)
    with pytest.raises(ModelError, match="needs --vehicle-drives 2 or more"):
        _drive(path, 5 + off, imu_noise_first=5 + off, imu_noise_earlier=1)  # K = 1: no earlier stretch


def test_a_recording_too_short_for_the_vehicles_is_one_line(tmp_path):
    path, _ = _recording(tmp_path)  # 70 000 samples: four drives of 150 s (15 001 samples)
    n = drive_samples(150.0, 100.0)
    check_vehicles(path, 5, [5, 6], 2, 150.0, 100.0)  # 2 vehicles × 2 drives = 4 stretches: they fit
    with pytest.raises(ModelError) as e:
        check_vehicles(path, 5, [5, 6], 3, 150.0, 100.0)
    msg = str(e.value)
    assert "\n" not in msg and f"[{5 * n}, {6 * n})" in msg
    for says in ("--imu-noise", "--vehicle-drives 3", "4 drive(s) fit, 1 vehicle(s)", "--seeds ≤ 1", "--duration"):
        assert says in msg, says
