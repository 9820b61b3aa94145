"""Gyro and accelerometer scale-factor states (KF-GINS' 21-state filter) as an EKF option
(docs/guide/theory.rst, 'Navigation filter')."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from imunoise.cli import build_parser, main
from imunoise.errors import ModelError
from imunoise.io.kfgins import ImuData
from imunoise.nav.defaults import DEG_PER_H, EkfConfig, default_axis_models
from imunoise.nav.ekf import InitialState, LooselyCoupledEKF, run_ekf
from imunoise.nav.error_states import ModelLayout, initial_covariance, scale_spec, swap_map
from imunoise.noise.processes import AR1
from imunoise.sim.drive import DriveConfig, simulate_drive

RATE = 100.0
TRUE_SCALE = np.array([0.0, 0.0, 3000e-6, 3000e-6, 0.0, 0.0])  # gyro z and accel x: 3000 ppm


@pytest.fixture(scope="module")
def scaled_drive():
    """A 300 s drive with turn-on biases and a known scale error: measured = (1 + s)·true + bias."""
    cfg = DriveConfig(
        duration_s=300.0,
        gnss_rate_hz=5.0,
        gnss_sigma_m=(0.05, 0.05, 0.05),
        n_stops=1,
        static_s=20.0,
        gyro_vibration=0.0,
        accel_vibration=0.0,
        seed=3,
    )
    d = simulate_drive(cfg, None, seed=3)
    imu = ImuData(
        t=d.imu.t,
        dtheta=d.imu.dtheta + TRUE_SCALE[:3] * d.imu_true.dtheta,
        dv=d.imu.dv + TRUE_SCALE[3:] * d.imu_true.dv,
    )
    r = d.reference
    init = InitialState(float(r.t[0]), r.llh[0], r.vel_ned[0], r.euler[0])
    return cfg, d, imu, init


def _layout(scale=None) -> ModelLayout:
    return ModelLayout.build(default_axis_models(RATE), 1.0 / RATE, scale)


def test_off_layout_is_unchanged_and_on_appends_six_scale_states():
    assert scale_spec(EkfConfig()) is None
    off, plain = _layout(scale_spec(EkfConfig())), _layout()
    for name in ("kind", "hvec", "P0", "phi_pow", "q_pow", "wpsd", "scale_index"):
        assert np.array_equal(getattr(off, name), getattr(plain, name)), name
    assert off.labels == plain.labels and np.all(off.scale_index == -1)

    cfg = EkfConfig(scale_factors=True, gyro_scale_std=2e-3, accel_scale_std=5e-4, scale_tau_s=1800.0)
    on = _layout(scale_spec(cfg))
    assert on.nm == plain.nm + 6
    idx = on.scale_index
    np.testing.assert_array_equal(idx, np.arange(plain.nm, plain.nm + 6))
    assert [on.labels[i] for i in idx] == [f"{a}.scale" for a in ("gyro_x", "gyro_y", "gyro_z",
                                                                   "accel_x", "accel_y", "accel_z")]
    assert np.all(on.hvec[idx] == 0.0) and np.all(on.kind[idx] == 3)
    np.testing.assert_array_equal(on.axis_of[idx], np.arange(6))
    # the noise-model block is untouched; the scale block is a GM with φ = exp(−dt/τ), q = σ²(1 − φ²)
    n0 = plain.nm
    assert np.array_equal(on.phi_pow[:, :n0, :n0], plain.phi_pow) and np.array_equal(on.q_pow[:, :n0, :n0], plain.q_pow)
    phi = math.exp(-0.01 / 1800.0)
    sig = np.array([2e-3] * 3 + [5e-4] * 3)
    np.testing.assert_allclose(np.diag(on.phi_pow[1])[idx], phi, rtol=1e-15)
    np.testing.assert_allclose(np.diag(on.q_pow[1])[idx], sig**2 * (1 - phi**2), rtol=1e-12)
    P0 = initial_covariance(cfg, on)
    np.testing.assert_array_equal(np.diag(P0)[9 + idx], sig**2)  # initial σ = stationary σ (KF-GINS)
    np.testing.assert_array_equal(P0[: 9 + n0, : 9 + n0], initial_covariance(cfg, plain))
    # a random constant: φ = 1, no process noise
    const = _layout(scale_spec(cfg.with_(scale_tau_s=math.inf)))
    assert np.all(np.diag(const.phi_pow[64])[idx] == 1.0) and np.all(const.q_pow[64][np.ix_(idx, idx)] == 0.0)


@pytest.mark.parametrize(
    "kw",
    [{"gyro_scale_std": 0.0}, {"accel_scale_std": -1e-3}, {"gyro_scale_std": math.nan}, {"scale_tau_s": 0.0}],
)
def test_bad_scale_settings_are_model_errors(kw):
    with pytest.raises(ModelError, match="scale"):
        scale_spec(EkfConfig(scale_factors=True, **kw))


@pytest.mark.parametrize("preserve", [False, True])
def test_swap_carries_scale_states_exactly(preserve):
    cfg = EkfConfig(scale_factors=True)
    old = _layout(scale_spec(cfg))
    faster = [m + AR1(phi=0.99, sigma2=1e-8) for m in default_axis_models(RATE)]
    new = ModelLayout.build(faster, 1.0 / RATE, scale_spec(cfg))
    rng = np.random.default_rng(4)
    n = 9 + old.nm
    A = rng.normal(size=(n, n))
    x, P = rng.normal(0, 1e-3, old.nm), A @ A.T * 1e-6
    res = swap_map(old, new, x, P, initial_covariance(cfg, new), preserve=preserve)
    io, inew = old.scale_index, new.scale_index
    np.testing.assert_array_equal(res.x[inew], x[io])  # with or without preserve: the scale is no noise model
    np.testing.assert_array_equal(res.P[np.ix_(9 + inew, 9 + inew)], P[np.ix_(9 + io, 9 + io)])
    np.testing.assert_array_equal(res.P[9 + inew, :9], P[9 + io, :9])
    assert res.kept == (12 if preserve else 6)  # 6 slow GMs (preserve only) + 6 scale factors
    # each axis' new bias is the old total additive error; the scale state does not enter that sum
    for a in range(6):
        o = [s for s in old.index(a) if s != io[a]]
        assert res.x[new.index(a)[0]] == pytest.approx(old.hvec[o] @ x[o] if not preserve else x[o[0]], rel=1e-14)
    # a filter without scale states swapped into one with them: they start fresh at 0 with σ²
    plain = _layout()
    xp, Pp = rng.normal(0, 1e-3, plain.nm), np.eye(9 + plain.nm) * 1e-6
    P0 = initial_covariance(cfg, old)
    fresh = swap_map(plain, old, xp, Pp, P0, preserve=preserve)
    assert np.all(fresh.x[io] == 0.0)
    np.testing.assert_array_equal(np.diag(fresh.P)[9 + io], np.diag(P0)[9 + io])


def test_off_ignores_the_scale_settings(scaled_drive):
    _, d, imu, init = scaled_drive
    sl = imu.slice(imu.t[0], imu.t[0] + 40.0)
    a = run_ekf(sl, d.gnss, init, EkfConfig(), None)
    b = run_ekf(sl, d.gnss, init, EkfConfig(gyro_scale_std=5e-3, accel_scale_std=1e-2, scale_tau_s=10.0), None)
    assert a.scale_factors is None and not any(lab.endswith(".scale") for lab in a.labels)
    for name in ("llh", "vel_ned", "euler", "gyro_error", "accel_error", "std"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_known_scale_errors_are_estimated_under_gnss(scaled_drive):
    """Gyro z and accel x scale errors of 3000 ppm (1·σ of a 5000 ppm random-constant prior) are recovered
    to < 800 ppm over 300 s of 5 cm GNSS (posterior σ ≈ 1100 ppm on this drive); without the states the
    gyro-z scale error leaks into the gyro-z bias estimate."""
    cfg, d, imu, init = scaled_drive
    base = EkfConfig(sigma_gyro_bias0=cfg.gyro_bias_sigma, sigma_accel_bias0=cfg.accel_bias_sigma)
    on_cfg = base.with_(scale_factors=True, gyro_scale_std=5e-3, accel_scale_std=5e-3, scale_tau_s=math.inf)
    on = run_ekf(imu, d.gnss, init, on_cfg, None)
    off = run_ekf(imu, d.gnss, init, base, None)
    s = on.scale_factors[-1]
    assert on.scale_factors.shape == (len(on.t), 6) and np.all(on.scale_factors[0] == 0.0)
    assert abs(s[2] - TRUE_SCALE[2]) < 800e-6, s * 1e6
    assert abs(s[3] - TRUE_SCALE[3]) < 800e-6, s * 1e6
    assert abs(s[4]) < 800e-6  # accel y: no scale error, none found
    true_bz = d.truth["turn_on_bias"]["gyro_rad_s"][2]
    err_on = abs(on.gyro_error[-1, 2] - true_bz) / DEG_PER_H
    err_off = abs(off.gyro_error[-1, 2] - true_bz) / DEG_PER_H
    assert err_on < 0.5 * err_off, (err_on, err_off)


def test_step_api_equals_batch_with_scale_factors(scaled_drive):
    _, d, imu, init = scaled_drive
    sl = imu.slice(imu.t[0], imu.t[0] + 60.0)
    gnss = d.gnss.slice(sl.t[0], sl.t[-1])
    ec = EkfConfig(cov_every=3, scale_factors=True)
    res = run_ekf(sl, gnss, init, ec, None)
    ekf = LooselyCoupledEKF(ec, None, init, imu_rate_hz=RATE)
    ekf.prime(sl.dtheta[0], sl.dv[0])
    gi = int(np.searchsorted(gnss.t, sl.t[0], side="right"))
    for k in range(1, len(sl)):
        ekf.propagate(sl.dtheta[k], sl.dv[k], sl.t[k])
        while gi < len(gnss) and gnss.t[gi] <= sl.t[k]:
            ekf.update_gnss(gnss.t[gi], gnss.llh[gi], gnss.sigma_ned[gi])
            gi += 1
    st = ekf.state()
    assert np.any(st["scale_factors"] != 0.0)
    np.testing.assert_allclose(st["scale_factors"], res.scale_factors[-1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(st["llh"][:2], res.llh[-1, :2], atol=1e-12)
    # a model swap keeps the scale estimates (docs/guide/theory.rst, 'Navigation filter' hot-swap)
    before = ekf.scale_factors()
    ekf.swap_model(None, preserve=False)
    np.testing.assert_array_equal(ekf.scale_factors(), before)


def test_cli_scale_factors_option(tmp_path):
    cfg = DriveConfig(duration_s=150.0, n_stops=1, static_s=35.0, gnss_rate_hz=5.0,
                      gnss_sigma_m=(0.05, 0.05, 0.1), seed=2)
    data = simulate_drive(cfg, None, seed=2).write(tmp_path / "sim")
    out = tmp_path / "nav"
    assert main(["nav", "--data", str(data), "--scale-factors", "--no-plots", "--out", str(out)]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert len(m["scale_factors_ppm"]) == 6 and all(math.isfinite(v) for v in m["scale_factors_ppm"])
    assert main(["nav", "--data", str(data), "--no-plots", "--out", str(tmp_path / "off")]) == 0
    assert "scale_factors_ppm" not in json.loads((tmp_path / "off" / "metrics.json").read_text())
    args = build_parser().parse_args(["online", "--data", str(data), "--scale-factors", "--out", str(tmp_path / "o")])
    assert args.scale_factors is True
