"""Motion-dependent IMU errors of the simulator (imunoise.sim.motion): "none" is exactly the static model,
the preset amplifies the moving errors by its designed factor, the oracle's models are the moving regime,
bad presets fail with the choices."""

from __future__ import annotations

import numpy as np
import pytest

from imunoise.cli import main as cli_main
from imunoise.errors import ModelError
from imunoise.imu import AXES
from imunoise.noise.wv import wavelet_variance
from imunoise.sim import DriveConfig, resolve_imu_models, simulate_drive
from imunoise.sim.imu_errors import simulate_model_errors
from imunoise.sim.motion import (
    DEFAULT_MOTION,
    DRIVE0708,
    MOTION_PRESETS,
    MotionNoise,
    modulated_errors,
    oracle_models,
    resolve_motion,
    scaled_models,
)

SHORT = dict(duration_s=300.0, n_stops=1)


def _drive(motion, seed: int = 3, imu="paper", **kw):
    return simulate_drive(DriveConfig(seed=seed, motion_noise=motion, **{**SHORT, **kw}), imu, seed=seed)


# ---- (a) "none" is the static model, bit for bit ------------------------------------------------------
def test_none_is_exactly_the_static_model_while_moving():
    d = _drive("none")
    n = len(d.imu.t)
    ss_imu = np.random.SeedSequence(3).spawn(4)[1]  # simulate_drive's IMU-error stream
    assert np.array_equal(d.model_errors, simulate_model_errors(d.imu_models, n, ss_imu))
    assert not d.vibration.any()  # no extra vibration in motion
    g, a = d.imu.rates()
    gt, at = d.imu_true.rates()
    e = np.column_stack([g - gt, a - at])
    np.testing.assert_allclose(e, d.bias_true, atol=1e-9)  # error = turn-on bias + the static model's path
    assert d.moving_models == d.imu_models
    assert d.truth["motion_noise"]["name"] == "none"


def test_unit_multipliers_reproduce_the_static_generator():
    """The modulated generator draws exactly what Model.simulate draws (every process kind)."""
    models = resolve_imu_models("2*AR1+WN+RW+QN+DR", 100.0)
    ones = np.ones((3000, 6))
    assert np.array_equal(modulated_errors(models, 3000, 5, ones, ones), simulate_model_errors(models, 3000, 5))
    assert MOTION_PRESETS["none"].is_static and not DRIVE0708.is_static


def test_the_law_changes_nothing_before_the_car_first_moves():
    """Same streams: with the preset the errors of the initial static period equal those of "none"."""
    d0, d1 = _drive("none"), _drive(DEFAULT_MOTION)
    first_move = int(np.argmax(~d1.static_mask))
    assert first_move > 5000  # the 60 s static start
    assert np.array_equal(d1.model_errors[:first_move], d0.model_errors[:first_move])
    assert not np.array_equal(d1.model_errors[first_move:], d0.model_errors[first_move:])
    assert np.array_equal(d1.imu_true.dtheta, d0.imu_true.dtheta)  # same trajectory


def test_legacy_vibration_stays_without_a_law():
    d = _drive(None)
    assert d.vibration[~d.static_mask].std() > 0 and not d.vibration[d.static_mask].any()
    assert d.truth["motion_noise"] is None


# ---- (b) the preset amplifies the moving errors by the designed factor ------------------------------------
def test_preset_amplifies_the_10s_adev_by_the_designed_factor():
    """At cruise (v ≥ v_ref) for 4000 s: the empirical Haar WV at τ = 1024 samples (10.24 s) of the modulated
    path over that of the static path (same seed), as an ADEV ratio, equals √(ν²_moving/ν²_static) of the
    models within 5 % (measured ≤ 0.5 % on seeds 0–2; both paths share their innovations). Designed factors
    of the paper preset at 10 s: gyro x 1.22, y 3.70, z 5.45 (x: white ×3 only, at 10 s mostly its RW)."""
    n = 400_000
    models = resolve_imu_models("paper", 100.0)
    mw, mb = DRIVE0708.multipliers(np.full(n, 10.0), np.zeros(n))
    moving = modulated_errors(models, n, 1, mw, mb)
    static = simulate_model_errors(models, n, 1)
    orc = oracle_models(models, DEFAULT_MOTION)
    designed = []
    for j, ax in enumerate(AXES[:3]):
        wm = wavelet_variance(moving[:, j], levels=10, freq=1.0)
        ws = wavelet_variance(static[:, j], levels=10, freq=1.0)
        assert wm.scales[-1] == 1024
        want = np.sqrt(orc[ax].wv(wm.scales[-1:]) / models[ax].wv(wm.scales[-1:]))[0]
        assert np.sqrt(wm.variance[-1] / ws.variance[-1]) == pytest.approx(want, rel=0.05)
        designed.append(want)
    assert designed == pytest.approx([1.22, 3.70, 5.45], abs=0.01)


# ---- (c) the oracle's models are the moving regime ------------------------------------------------------
def test_oracle_models_match_the_simulated_moving_errors():
    """On a simulated drive: the Haar WV of the moving error segments (each run after its first 20 s, levels
    1–6 = 0.02–0.64 s) matches the drive's moving-regime models within 15 % (measured 0.94–1.09 on seeds
    0–2, 600 s drives; AR1 and white noise dominate these scales); the static models are off by the
    designed factor."""
    d = _drive(DEFAULT_MOTION, seed=0, duration_s=600.0, n_stops=4)
    edges = np.diff(np.concatenate([[0], (~d.static_mask).astype(np.int8), [0]]))
    runs = [(a + 2000, b) for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True)
            if b - a > 4000]
    for j, ax in enumerate(AXES):
        wv = wavelet_variance([d.model_errors[a:b, j] for a, b in runs], levels=6, freq=1.0)
        np.testing.assert_allclose(wv.variance / d.moving_models[ax].wv(wv.scales), 1.0, atol=0.15)
        # at τ = 2 samples white noise dominates: ×3 (gyro) or ×7 (accel) in σ
        assert wv.variance[0] / d.imu_models[ax].wv(wv.scales[:1])[0] > 4.0
    # the moving models are the static ones scaled by the RMS multipliers over the moving samples
    assert d.moving_models["gyro_x"].params["RW.gamma2"] == d.imu_models["gyro_x"].params["RW.gamma2"]
    ratio = d.moving_models["gyro_z"].params["RW.gamma2"] / d.imu_models["gyro_z"].params["RW.gamma2"]
    assert 4.5**2 < ratio <= 5.8**2  # 1 + 4.8·min(v/3, 1), RMS over the moving samples (ramps included)


def test_scenario_oracle_uses_the_moving_models():
    from imunoise.experiments.common import SIM_MOTION, filter_models, simulate_scenario
    from imunoise.experiments.online_exp import method_config

    assert SIM_MOTION == DEFAULT_MOTION
    for motion in ("none", DEFAULT_MOTION):
        sc = simulate_scenario(2, n_outages=0, motion_noise=motion, **SHORT)
        cfg, models = method_config("oracle", sc)
        want = filter_models([sc.truth_models[ax] for ax in AXES], sc.rate, cfg.with_(floor="none"))
        assert all(m.params == pytest.approx(w.params) for m, w in zip(models, want, strict=True))
        same = sc.truth_models == sc.extra["static_models"]
        assert same == (motion == "none")


def test_scaled_models_keep_the_correlation_times():
    models = resolve_imu_models("mems", 100.0)
    out = scaled_models(models, np.full(6, 2.0), np.full(6, 3.0))
    for ax in AXES:
        a, b = models[ax].params, out[ax].params
        assert b["WN.sigma2"] == pytest.approx(4 * a["WN.sigma2"])
        assert b["RW.gamma2"] == pytest.approx(9 * a["RW.gamma2"])
        assert [b[k] for k in b if k.endswith("phi")] == [a[k] for k in a if k.endswith("phi")]


# ---- (d) bad input --------------------------------------------------------------------------------------
def test_bad_preset_lists_the_choices(capsys, tmp_path):
    with pytest.raises(ModelError, match="none, drive0708"):
        resolve_motion("bogus")
    with pytest.raises(ModelError, match="motion-noise preset 'bogus'"):
        DriveConfig(motion_noise="bogus")
    with pytest.raises(ModelError, match="bias_speed"):
        MotionNoise(bias_speed=(1.0, -1.0, 0.0, 0.0, 0.0, 0.0))
    assert cli_main(["simulate", "--motion-noise", "bogus", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "none, drive0708" in err[0]
    assert not (tmp_path / "x").exists()
    assert cli_main(["experiment", "online", "--motion-noise", "none", "--out", str(tmp_path / "y")]) == 2
    assert "--sim" in capsys.readouterr().err


def test_cli_default_is_the_calibrated_preset(tmp_path):
    import json

    assert cli_main(["simulate", "--duration", "200", "--stops", "0", "--out", str(tmp_path / "d")]) == 0
    truth = json.loads((tmp_path / "d" / "truth.json").read_text())
    assert truth["motion_noise"]["name"] == DEFAULT_MOTION and "models_moving" in truth
    assert cli_main(["simulate", "--duration", "200", "--stops", "0", "--motion-noise", "none",
                     "--out", str(tmp_path / "n")]) == 0
    truth = json.loads((tmp_path / "n" / "truth.json").read_text())
    assert truth["models_moving"] == truth["models"]
