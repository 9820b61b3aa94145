"""Simulator: truth consistency, exact increments (noise-free INS), error injection statistics, GNSS,
files and CLI (docs/guide/theory.rst, 'Simulator', issue 4 acceptance 1)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from imunoise.cli import main as cli_main
from imunoise.errors import ImunoiseError, ModelError
from imunoise.imu import AXES
from imunoise.io.kfgins import read_gnss, read_imu, read_outages, read_reference
from imunoise.nav.earth import OMEGA_E, gravity, llh_to_ned, radii
from imunoise.noise.model import Model
from imunoise.noise.processes import AR1, RW, WN
from imunoise.sim import DriveConfig, preset_model, resolve_imu_models, simulate_drive, simulate_static

DEG = math.pi / 180.0


@pytest.fixture(scope="module")
def clean_drive():
    """10 min urban drive without any IMU error (shared by the truth tests)."""
    return simulate_drive(DriveConfig.noise_free(duration_s=600.0, n_stops=3), None, seed=11)


def test_position_is_the_integral_of_velocity(clean_drive):
    r = clean_drive.reference_full
    dt = np.diff(r.t)
    rm, rn = radii(r.llh[:-1, 0])
    h = r.llh[:-1, 2]
    dn = np.diff(r.llh[:, 0]) * (rm + h)
    de = np.diff(r.llh[:, 1]) * (rn + h) * np.cos(r.llh[:-1, 0])
    dd = -np.diff(r.llh[:, 2])
    vm = 0.5 * (r.vel_ned[1:] + r.vel_ned[:-1])
    err = np.column_stack([dn, de, dd]) - vm * dt[:, None]
    assert np.abs(err).max() < 1e-5  # m per 10 ms step (trapezoid error ~ jerk·dt³/12)
    # velocity is along body x (no side slip): v^n ∥ C_b^n e_x
    speed = np.linalg.norm(r.vel_ned, axis=1)
    yaw = np.arctan2(r.vel_ned[:, 1], r.vel_ned[:, 0])
    mv = speed > 1.0
    assert np.abs(np.angle(np.exp(1j * (yaw[mv] - r.euler[mv, 2])))).max() < 1e-9


def test_stops_turns_and_static_mask(clean_drive):
    d = clean_drive
    cfg = d.config
    r = d.reference_full
    speed = np.linalg.norm(r.vel_ned, axis=1)
    stops = d.truth["stops"]
    assert len(stops) == cfg.n_stops
    for a, b in stops:
        assert cfg.stop_range_s[0] - 1e-6 <= b - a <= cfg.stop_range_s[1] + 1e-6
        inside = (r.t >= a) & (r.t < b - 1e-6)
        assert inside.sum() > 100 and np.all(speed[inside] == 0.0)
        assert d.static_mask[inside][1:].all()  # first sample's interval may still contain the stop's onset
    # static start, driving, final stop; nothing moves on static epochs
    assert d.static_mask[: int(cfg.static_s * cfg.imu_rate_hz) - 1].all()
    assert not d.static_mask.all() and speed.max() > 8.0
    assert np.all(speed[d.static_mask] < 0.05)
    g, _ = d.imu_true.rates()
    w_ie = OMEGA_E * np.array([np.cos(r.llh[:, 0]), np.zeros(len(r.t)), -np.sin(r.llh[:, 0])]).T
    w_ie_b = np.einsum("nji,nj->ni", _dcm(r.euler), w_ie)
    rest = _at_rest(d)
    assert rest.sum() > 0.97 * d.static_mask.sum()
    np.testing.assert_allclose(g[rest], w_ie_b[rest], atol=1e-12)
    # tight corners: body yaw rate above 30 °/s somewhere, and the truth records it
    assert np.abs(np.degrees(g[:, 2])).max() > 30.0
    assert d.truth["max_turn_rate_deg_s"] > 30.0
    assert any(t["kind"] == "corner" for t in d.truth["turns"])
    # gentle grades and small roll
    assert 0.2 < np.degrees(np.abs(r.euler[:, 1])).max() <= cfg.max_grade_deg + 1e-9
    assert np.degrees(np.abs(r.euler[:, 0])).max() < 2.0


def _at_rest(d) -> np.ndarray:
    """Static epochs whose whole interval is at exactly zero speed (not creeping to a halt)."""
    m = d.static_mask & (np.linalg.norm(d.reference_full.vel_ned, axis=1) == 0)
    m[1:] &= m[:-1]
    return m


def _dcm(euler: np.ndarray) -> np.ndarray:
    from imunoise.sim.trajectory import euler_to_dcm_many

    return euler_to_dcm_many(euler[:, 0], euler[:, 1], euler[:, 2])


def test_specific_force_at_rest_is_gravity(clean_drive):
    d = clean_drive
    r = d.reference_full
    f = d.imu_true.dv * d.config.imu_rate_hz  # nominal Δt: stamps near 1e5 s carry ~1e-9 relative jitter
    m = _at_rest(d)
    np.testing.assert_allclose(np.linalg.norm(f[m], axis=1), gravity(r.llh[m, 0], r.llh[m, 2]), rtol=0, atol=1e-9)


@pytest.mark.slow
def test_noise_free_ins_stays_within_half_metre(clean_drive):
    """Issue 4 acceptance 1: exact increments + two-sample mechanization, 10 min urban drive."""
    from imunoise.nav.mechanization import integrate

    d = clean_drive
    r = d.reference_full
    imu = d.imu_true
    llh, vel, eul = integrate(imu.t, imu.dtheta, imu.dv, r.llh[0], r.vel_ned[0], r.euler[0])
    ned = llh_to_ned(llh[::100], r.llh[0]) - llh_to_ned(r.llh[::100], r.llh[0])
    horiz = np.hypot(ned[:, 0], ned[:, 1])
    assert horiz.max() < 0.5 and horiz[-1] < 0.1  # measured: 0.02 m
    assert np.abs(vel - r.vel_ned).max() < 1e-3
    assert np.abs(np.angle(np.exp(1j * (eul - r.euler)))).max() < 1e-5


def test_error_injection_identities():
    """With errors: imu − imu_true = (bias + model + vibration)·dt; vibration is exactly absent at rest."""
    cfg = DriveConfig(duration_s=300.0, n_stops=1, gyro_vibration=0.05, accel_vibration=0.5, seed=4)
    d = simulate_drive(cfg, {"gyro": Model([WN(sigma2=1e-6)]), "az": "WN"}, seed=4)
    g, a = d.imu.rates()
    gt, at = d.imu_true.rates()
    e = np.column_stack([g - gt, a - at])
    bias = np.concatenate([d.truth["turn_on_bias"]["gyro_rad_s"], d.truth["turn_on_bias"]["accel_m_s2"]])
    m = d.static_mask
    # accel x, y have no model: at rest the error is the turn-on bias, exactly
    np.testing.assert_allclose(e[m][:, 3:5], np.broadcast_to(bias[3:5], (m.sum(), 2)), atol=1e-9)
    # moving: vibration adds a large white error (σ 0.5 m/s² at speed)
    assert e[~m][:, 3].std() > 0.2 and np.abs(e[m][:, 3] - bias[3]).max() < 1e-9
    # gyro WN σ² = 1e-6 at rest
    r = e[m][:, :3] - bias[:3]
    assert np.all(np.abs(r.var(axis=0) / 1e-6 - 1) < 5 * math.sqrt(2 / m.sum()))
    assert d.truth["models"]["gyro_x"]["model"] == "WN" and "accel_x" not in d.truth["models"]
    assert d.truth["models"]["accel_z"]["params"]["WN.sigma2"] == pytest.approx((70e-6 * 9.80665) ** 2 * 100)
    np.testing.assert_allclose(e[:, :3], d.bias_true[:, :3] + d.vibration[:, :3], atol=1e-12)
    # the trajectory does not depend on the IMU model (separate random streams)
    d2 = simulate_drive(cfg, None, seed=4)
    assert np.array_equal(d2.imu_true.dv, d.imu_true.dv)


def test_scale_factor_enters_proportionally():
    cfg = DriveConfig.noise_free(duration_s=200.0, n_stops=0, scale_factor_sigma=1e-3, seed=2)
    d = simulate_drive(cfg, None)
    s = np.concatenate([d.truth["scale_factor"]["gyro"], d.truth["scale_factor"]["accel"]])
    meas = np.column_stack(d.imu.increments())
    true = np.column_stack(d.imu_true.increments())
    np.testing.assert_allclose(meas, true * (1 + s), rtol=1e-12, atol=1e-18)


def test_static_recording_statistics():
    """The paper's static test: rates = Earth rate + gravity + model errors with the requested statistics."""
    phi, s2, wn = 0.995, 1e-6, 1e-4
    model = AR1(phi=phi, sigma2=s2) + WN(sigma2=wn)
    rec = simulate_static({"gx": model, "ax": Model([WN(sigma2=4e-4)])}, 2 * 3600.0, 100.0, seed=7)
    n = len(rec.t)
    assert n == 720_000 and rec.rates.shape == (n, 6)
    lat = math.radians(40.0966)
    np.testing.assert_allclose(rec.rates_true[0, :3], [OMEGA_E * math.cos(lat), 0, -OMEGA_E * math.sin(lat)])
    assert rec.rates_true[0, 5] == pytest.approx(-gravity(lat, 1601.0))
    np.testing.assert_array_equal(rec.rates[:, [1, 2, 4, 5]], rec.rates_true[:, [1, 2, 4, 5]])
    x = rec.errors[:, 0]
    var_gm = s2 / (1 - phi * phi)
    n_eff = n * (1 - phi) / (1 + phi)
    assert x.var() == pytest.approx(var_gm + wn, rel=4 * math.sqrt(2 / n_eff) * var_gm / (var_gm + wn) + 0.01)
    lag1 = np.mean((x[1:] - x.mean()) * (x[:-1] - x.mean()))
    assert lag1 == pytest.approx(phi * var_gm, rel=0.15)
    assert rec.errors[:, 3].std() == pytest.approx(0.02, rel=4 * math.sqrt(0.5 / n))
    np.testing.assert_allclose(rec.increments[:, 3], rec.rates[:, 3] * 0.01)


def test_presets_and_model_resolution(tmp_path):
    m = preset_model("mems", "gyro", "3*AR1+WN+RW", 100.0)
    c = m.continuous(100.0)
    assert c["WN.noise_density"] == pytest.approx(0.0038 * DEG)
    assert c["RW.random_walk"] == pytest.approx(0.5 * DEG / 3600)
    assert [round(c[f"AR1_{i}.tau_c"]) for i in (1, 2, 3)] == [200, 20, 2]
    assert preset_model("mems", "gyro", "WN", 200.0).params["WN.sigma2"] == pytest.approx((0.0038 * DEG) ** 2 * 200)
    models = resolve_imu_models("2*AR1+WN", 100.0)
    assert tuple(models) == AXES and str(models["accel_x"]) == "2*AR1 + WN"
    known = AR1(phi=0.99, sigma2=1e-6) + RW(gamma2=1e-12)
    p = tmp_path / "m.json"
    # "az": the short axis names of older truth files are still read, and come out as imu.AXES names
    p.write_text(json.dumps({"gyro": known.to_dict(), "az": {"model": "WN", "params": {"WN.sigma2": 1e-3}}}))
    models = resolve_imu_models(str(p), 100.0)
    assert models["gyro_y"] == known and models["accel_z"].params == {"WN.sigma2": 1e-3} and "accel_x" not in models
    assert set(models) == {"gyro_x", "gyro_y", "gyro_z", "accel_z"}
    assert resolve_imu_models(None, 100.0) == {}
    with pytest.raises(ModelError, match="axis"):
        resolve_imu_models({"gw": "WN"}, 100.0)
    with pytest.raises(ModelError, match="preset"):
        preset_model("nope", "gyro", "WN", 100.0)


def test_gnss_noise_outliers_outages_and_lever_arm():
    cfg = DriveConfig.noise_free(
        duration_s=600.0,
        n_stops=2,
        gnss_rate_hz=5.0,
        gnss_sigma_m=(0.5, 1.0, 2.0),
        outlier_rate=0.02,
        outages=[(100.0, 60.0), (300.0, 30.0)],
        remove_outages=True,
        lever_arm_m=(1.0, -0.5, -1.5),
        seed=5,
    )
    d = simulate_drive(cfg, None)
    assert len(d.gnss_full) == 600 * 5 + 1
    assert len(d.gnss) == len(d.gnss_full) - 90 * 5
    ref = d.reference_full
    idx = np.searchsorted(ref.t, d.gnss_full.t)
    np.testing.assert_allclose(ref.t[idx], d.gnss_full.t)
    ant = np.einsum("nij,j->ni", _dcm(ref.euler[idx]), np.array(cfg.lever_arm_m))
    err = np.array([llh_to_ned(g, r) for g, r in zip(d.gnss_full.llh, ref.llh[idx], strict=True)]) - ant
    out = np.isin(d.gnss_full.t, d.truth["gnss_outliers_t"])
    assert 20 <= out.sum() <= 100 and np.all(np.hypot(err[out, 0], err[out, 1]) > 5.0)
    sd = err[~out].std(axis=0)
    np.testing.assert_allclose(sd, cfg.gnss_sigma_m, rtol=0.1)
    np.testing.assert_allclose(d.gnss.sigma_ned[0], cfg.gnss_sigma_m)
    # antenna reference: offset C_b^n l from the IMU; its velocity is the finite difference of its position
    ra, ri = d.reference_antenna, d.reference
    off = np.array([llh_to_ned(x, y) for x, y in zip(ra.llh, ri.llh, strict=True)])
    np.testing.assert_allclose(off, np.einsum("nij,j->ni", _dcm(ri.euler), np.array(cfg.lever_arm_m)), atol=1e-6)
    ned = llh_to_ned(ra.llh, ra.llh[0])
    vfd = np.diff(ned, axis=0) / np.diff(ra.t)[:, None]
    vmid = 0.5 * (ra.vel_ned[1:] + ra.vel_ned[:-1])
    assert np.abs(vfd - vmid).max() < 0.05 and np.abs(ra.vel_ned - ri.vel_ned).max() > 0.3


def test_write_and_read_back(tmp_path):
    cfg = DriveConfig(duration_s=240.0, n_stops=1, outages=[(150.0, 20.0)], seed=9)
    d = simulate_drive(cfg, "mems")
    out = d.write(tmp_path / "drive")
    man = json.loads((out / "dataset.json").read_text())
    for key in (
        "name",
        "imu",
        "imu_kind",
        "gnss",
        "ref",
        "outages",
        "lever_arm_m",
        "imu_time_offset_s",
        "license",
    ):
        assert key in man
    imu = read_imu(out / man["imu"])
    np.testing.assert_allclose(imu.t, d.imu.t, atol=1e-9, rtol=0)
    np.testing.assert_allclose(imu.dtheta, d.imu.dtheta, rtol=1e-12, atol=1e-300)
    np.testing.assert_allclose(imu.dv, d.imu.dv, rtol=1e-12)
    gnss = read_gnss(out / man["gnss"])
    np.testing.assert_allclose(gnss.llh[:, :2], d.gnss.llh[:, :2], atol=1e-13, rtol=0)
    ref = read_reference(out / man["ref"])
    assert len(ref) == 2401 and (ref.week == cfg.gps_week).all() and man["ref_point"] == "antenna"
    np.testing.assert_allclose(ref.euler, d.reference.euler, atol=1e-10)
    ref_imu = read_reference(out / man["ref_imu"])
    np.testing.assert_allclose(ref_imu.llh[:, :2], d.reference.llh[:, :2], atol=1e-13, rtol=0)
    np.testing.assert_allclose(ref_imu.vel_ned, d.reference.vel_ned, atol=1e-6, rtol=0)
    assert read_outages(out / man["outages"]) == [(cfg.start_sow + 150.0, 20.0)]
    truth = json.loads((out / "truth.json").read_text())
    assert len(truth["stops"]) == 1 and truth["models"]["gyro_x"]["model"] == "3*AR1 + WN + RW"
    assert Model.from_dict(truth["models"]["accel_z"]) == d.imu_models["accel_z"]
    assert truth["turn_on_bias"]["axes"] == list(AXES)


def test_cli_simulate(tmp_path, capsys):
    rc = cli_main(
        [
            "simulate",
            "--duration",
            "200",
            "--stops",
            "1",
            "--imu-model",
            "2*AR1+WN+RW",
            "--seed",
            "3",
            "--gnss-rate",
            "2",
            "--out",
            str(tmp_path / "d"),
        ]
    )
    assert rc == 0 and "stops" in capsys.readouterr().out
    assert len(read_gnss(tmp_path / "d" / "gnss.txt")) == 401
    truth = json.loads((tmp_path / "d" / "truth.json").read_text())
    assert truth["models"]["gyro_z"]["model"] == "2*AR1 + WN + RW"
    rc = cli_main(["simulate", "--static", "--duration", "30", "--imu-model", "mems", "--out", str(tmp_path / "s")])
    assert rc == 0
    a = read_imu(tmp_path / "s" / "imu.txt")
    b = read_imu(tmp_path / "s" / "imu_rate.csv")
    assert len(a) == 3000 and np.allclose(a.dv, b.dv, rtol=1e-9)
    assert cli_main(["simulate", "--duration", "100", "--stops", "5", "--out", str(tmp_path / "x")]) == 2
    assert "too short" in capsys.readouterr().err
    assert cli_main(["simulate", "--imu-model", "3*XYZ", "--out", str(tmp_path / "y")]) == 2


def test_bad_configs():
    with pytest.raises(ImunoiseError):
        DriveConfig(duration_s=100.0, static_s=200.0)
    with pytest.raises(ImunoiseError, match="divide"):
        simulate_drive(DriveConfig(duration_s=200.0, n_stops=0, gnss_rate_hz=3.0))
    with pytest.raises(ImunoiseError):
        DriveConfig(gnss_sigma_m=(0.0, 1.0, 1.0))


def test_outage_windows_fall_in_motion(clean_drive):
    d = clean_drive
    wins = d.outage_windows(5, 60.0)
    assert len(wins) == 5
    starts = np.array([w[0] for w in wins])
    assert np.all(np.diff(starts) >= 60.0)
    r = d.reference_full
    speed = np.linalg.norm(r.vel_ned, axis=1)
    i0 = np.searchsorted(r.t, starts)
    assert np.sum(speed[i0] >= 2.0) >= 4
    moved = [np.sum(speed[a : a + 6000]) * 0.01 for a in i0]
    assert min(moved) > 100.0  # m of road under every outage
    assert starts[0] >= d.truth["static_intervals"][0][1] and starts[-1] + 60 <= d.truth["static_intervals"][-1][0]
    with pytest.raises(ImunoiseError, match="cannot fit"):
        d.outage_windows(10, 60.0)
    # a lead keeps the first window that long after the static start, and the rest still fit
    led = d.outage_windows(4, 60.0, lead_s=120.0)
    assert led[0][0] >= d.truth["static_intervals"][0][1] + 120.0
    assert np.all(np.diff([w[0] for w in led]) >= 60.0)
    with pytest.raises(ImunoiseError, match="lead"):
        d.outage_windows(5, 60.0, lead_s=1e4)
    with pytest.raises(ImunoiseError, match="lead_s"):
        d.outage_windows(2, 60.0, lead_s=-1.0)


def test_paper_preset_is_table4():
    """The "paper" preset reproduces paper Table 4 exactly at 125 Hz and keeps its continuous values at 100 Hz."""
    from imunoise.sim.imu_errors import PAPER_TABLE4_GYRO, paper_models, preset_model

    m125 = resolve_imu_models("paper", 125.0)
    for ax, (ars, wn, rw) in PAPER_TABLE4_GYRO.items():
        p = m125[ax].params
        assert str(m125[ax]) == "3*AR1 + WN + RW"
        got = sorted((p[f"AR1_{i}.sigma2"], p[f"AR1_{i}.phi"]) for i in (1, 2, 3))
        assert np.allclose(got, sorted(ars), rtol=1e-12, atol=0)
        assert p["WN.sigma2"] == pytest.approx(wn, rel=1e-12) and p["RW.gamma2"] == pytest.approx(rw, rel=1e-12)
    m100 = paper_models(100.0)
    for ax in ("gyro_x", "gyro_y", "gyro_z"):
        c125, c100 = m125[ax].continuous(125.0), m100[ax].continuous(100.0)
        for k in c125:
            if not k.endswith("q_c"):
                assert c100[k] == pytest.approx(c125[k], rel=1e-9), k
    acc = preset_model("mems", "accel", "3*AR1+WN+RW", 100.0)
    assert m100["accel_z"].params == pytest.approx(acc.params)
    # the RW of Table 4 gyro z is K = 5.6e-5 rad/s/√s (11.5 °/h/√s), 23× the plain default's
    assert m100["gyro_z"].continuous(100.0)["RW.random_walk"] == pytest.approx(5.597e-5, rel=1e-3)


def test_correlated_gnss_noise():
    cfg = DriveConfig.noise_free(duration_s=1200.0, n_stops=0, gnss_rate_hz=5.0, gnss_noise_tau_s=2.0, seed=1)
    d = simulate_drive(cfg, None)
    ref = d.reference_full
    idx = np.searchsorted(ref.t, d.gnss_full.t)
    e = llh_to_ned(d.gnss_full.llh, ref.llh[0]) - llh_to_ned(ref.llh[idx], ref.llh[0])
    np.testing.assert_allclose(e.std(axis=0), cfg.gnss_sigma_m, rtol=0.15)
    r1 = np.mean(e[1:, 0] * e[:-1, 0]) / e[:, 0].var()
    assert r1 == pytest.approx(math.exp(-1.0 / (2.0 * 5.0)), abs=0.05)
