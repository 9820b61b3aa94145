"""Error laws as files (imunoise.sim.motion.load_law, src/imunoise/sim/laws/): the presets are files with the
same results to the bit, each additive term has the statistics of its definition, a malformed file is one line
naming the key and exit 2."""

from __future__ import annotations

import json
import math
from importlib import resources

import numpy as np
import pytest

from imunoise.cli import main as cli_main
from imunoise.errors import ModelError
from imunoise.sim import DriveConfig, simulate_drive
from imunoise.sim.law_terms import departure_steps, departures, moving_gauss_markov, warmup_bias
from imunoise.sim.motion import LAWS, MotionNoise, load_law, resolve_motion

SHORT = dict(duration_s=300.0, n_stops=2)
# the presets as they were defined in code before they became files
OLD = {"none": MotionNoise(name="none"),
       "drive0708": MotionNoise(name="drive0708", white_speed=(2.0, 2.0, 2.0, 6.0, 6.0, 6.0),
                                bias_speed=(0.0, 2.75, 4.8, 0.0, 0.0, 0.0))}


def _imu(motion, seed=3):
    d = simulate_drive(DriveConfig(seed=seed, motion_noise=motion, **SHORT), "paper", seed=seed)
    return d, np.column_stack([d.imu.dtheta, d.imu.dv])


@pytest.mark.parametrize("name", ["none", "drive0708"])
def test_preset_files_reproduce_the_presets_to_the_bit(name):
    assert LAWS[name] == OLD[name]
    _, by_name = _imu(name)
    _, by_code = _imu(OLD[name])
    _, by_path = _imu(str(resources.files("imunoise.sim").joinpath("laws", f"{name}.json")))
    assert np.array_equal(by_name, by_code) and np.array_equal(by_name, by_path)


def test_shipped_laws_are_documented_and_carry_one_term_each():
    assert list(LAWS)[:2] == ["none", "drive0708"]
    terms = {"gyro_departure_step": "departure_step", "gyro_moving_gm": "moving_gm_sigma",
             "accel_moving_gm": "moving_gm_sigma", "warmup": "warmup_amplitude"}
    for name, term in terms.items():
        law = LAWS[name]
        assert law.name == name and not law.modulates and law.has_terms
        assert all(not any(getattr(law, k)) for k in ("moving_gm_sigma", "departure_step", "warmup_amplitude")
                   if k != term)
    dph = math.pi / 180 / 3600
    assert LAWS["gyro_departure_step"].departure_step[:3] == pytest.approx((150 * dph,) * 3)
    assert not any(LAWS["accel_moving_gm"].moving_gm_sigma[:3]) and not any(LAWS["gyro_moving_gm"].moving_gm_sigma[3:])
    for f in resources.files("imunoise.sim").joinpath("laws").iterdir():
        assert len(json.loads(f.read_text())["doc"]) > 80, f.name


def _mask(n, rng, stops=400):
    m = np.zeros(n, dtype=bool)
    for s in rng.integers(0, n - 600, stops):
        m[s:s + rng.integers(100, 500)] = True
    return m


def test_moving_gauss_markov_variance_correlation_time_and_freeze():
    rng = np.random.default_rng(1)
    n, f, sigma, tau = 400_000, 100.0, 0.5, 2.0
    mask = _mask(n, rng)
    x = moving_gauss_markov(mask, f, np.full(6, sigma), np.full(6, tau), rng)
    held = np.diff(x, axis=0)[mask[1:]]
    assert not held.any()  # frozen at stops, to the bit
    mv = x[~mask]  # the moving samples: a plain AR(1) at rate f
    assert np.var(mv) == pytest.approx(sigma ** 2, rel=0.06)
    phi = np.mean([np.corrcoef(mv[1:, j], mv[:-1, j])[0, 1] for j in range(6)])
    assert -1.0 / (f * math.log(phi)) == pytest.approx(tau, rel=0.1)
    assert not moving_gauss_markov(mask, f, np.zeros(6), np.full(6, tau), rng).any()


def test_departure_step_sigma_from_many_departures():
    rng = np.random.default_rng(2)
    mask = _mask(2_000_000, rng, stops=3000)
    b = departure_steps(mask, np.full(6, 0.3), rng)
    k = departures(mask)
    assert k.size > 1500
    jumps = np.diff(b, axis=0)
    assert np.count_nonzero(np.any(jumps != 0, axis=1)) == k.size  # steps only at departures
    assert np.std(jumps[k - 1]) == pytest.approx(0.3, rel=0.03)
    assert not b[: k[0]].any()


def test_warmup_is_the_exact_curve_in_a_simulated_drive():
    t = np.arange(0.0, 1000.0, 0.01)
    amp = np.array([1e-3, -2e-3, 5e-4, 0.02, -0.01, 0.03])
    w = warmup_bias(t, amp, 600.0)
    np.testing.assert_allclose(w, amp * (1 - np.exp(-t / 600.0))[:, None], rtol=1e-12, atol=0)
    law = MotionNoise(name="w", warmup_amplitude=tuple(amp), warmup_tau_s=600.0)
    d0, a0 = _imu("none")
    d1, a1 = _imu(law)
    dt = np.diff(d0.imu.t)[0]
    want = amp * -np.expm1(-(d0.imu.t - d0.imu.t[0]) / 600.0)[:, None]
    np.testing.assert_allclose((a1 - a0) / dt, want, rtol=0, atol=1e-10)  # rounding of Δv = f·Δt only


def test_acceleration_activity_enters_both_multipliers():
    law = MotionNoise(white_accel=(1.0,) * 6, bias_accel=(0.0, 2.0, 0, 0, 0, 0), accel_ref_mps2=2.0)
    mw, mb = law.multipliers(np.zeros(3), np.zeros(3), accel=np.array([0.0, 1.0, 5.0]))
    np.testing.assert_allclose(mw[:, 0], [1.0, 1.5, 2.0])
    np.testing.assert_allclose(mb[:, 1], [1.0, 2.0, 3.0])


@pytest.mark.parametrize("content,key", [
    ({"white": {"speed": [1, 2]}}, "'white.speed'"),
    ({"moving_gm": {"sigma": [0.1] * 6}}, "'moving_gm.tau_s'"),
    ({"departure_step": [0.1, -1, 0, 0, 0, 0]}, "'departure_step'"),
    ({"warmup": {"amplitude": [0] * 6, "tau_s": 0}}, "'warmup.tau_s'"),
    ({"wobble": 1}, "'wobble'"),
    ({"bias": {"jerk": [0] * 6}}, "'bias.jerk'"),
])
def test_malformed_law_file_is_one_line_naming_the_key(tmp_path, capsys, content, key):
    f = tmp_path / "law.json"
    f.write_text(json.dumps(content))
    with pytest.raises(ModelError, match=key):
        load_law(f)
    assert cli_main(["simulate", "--motion-noise", str(f), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and key in err[0] and str(f) in err[0]
    assert cli_main(["experiment", "online", "--sim", "--motion-noise", str(f), "--out", str(tmp_path / "y")]) == 2
    assert key in capsys.readouterr().err
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()


def test_a_law_file_runs_the_simulator_and_names_itself(tmp_path):
    f = tmp_path / "mine.json"
    f.write_text(json.dumps({"departure_step": [1e-3] * 3 + [0] * 3}))
    law = resolve_motion(str(f))
    assert law.name == "mine" and law.departure_step[0] == 1e-3
    d, a = _imu(str(f))
    _, a0 = _imu("none")
    assert d.truth["motion_noise"]["name"] == "mine"
    k = departures(d.static_mask)
    assert k.size == 3 and np.array_equal(a[: k[0]], a0[: k[0]])  # start + 2 stops; nothing changes before
    assert not np.array_equal(a[k[0]:, 0], a0[k[0]:, 0])
    assert np.array_equal(a[:, 3:], a0[:, 3:])  # accelerometers untouched


def test_law_schedule_is_what_the_simulator_injects():
    from imunoise.sim.law_schedule import warmup_random_walk
    from imunoise.sim.motion import modulated_errors

    d, _ = _imu("drive0708")
    s = d.law_schedule
    n = len(d.imu.t)
    ss_imu = np.random.SeedSequence(3).spawn(4)[1]
    again = modulated_errors(d.imu_models, n, ss_imu, np.sqrt(s.white_var_scale), np.sqrt(s.bias_var_scale))
    np.testing.assert_allclose(again, d.model_errors, rtol=1e-12, atol=1e-18)
    assert np.array_equal(s.moving, ~d.static_mask) and np.all(s.white_var_scale[d.static_mask] == 1.0)
    assert s.white_var_scale[:, 3].max() == pytest.approx(49.0)  # (1 + 6)² at cruise
    assert s.departure_index.size == 3 and not s.step_var.any() and not s.warmup_rw_q.any()
    cp = s.change_points()
    assert cp[0] == 0 and set(s.departure_index) <= set(cp)
    # the warm-up's closest random walk: variance after the drive = the warm-up's squared total change
    q = warmup_random_walk(np.array([2.0]), 600.0, 300.0)
    assert q[0] * 300.0 == pytest.approx((2.0 * (1 - math.exp(-0.5))) ** 2)
    step = _imu("gyro_departure_step")[0].law_schedule
    assert step.step_var[:3] == pytest.approx([LAWS["gyro_departure_step"].departure_step[0] ** 2] * 3)
    assert simulate_drive(DriveConfig(seed=1, **SHORT), "paper", seed=1).law_schedule is None


def test_simulate_cli_takes_a_law_file(tmp_path):
    f = tmp_path / "mine.json"
    f.write_text(json.dumps({"name": "bench_step", "departure_step": [1e-3] * 3 + [0] * 3}))
    assert cli_main(["simulate", "--duration", "200", "--stops", "1", "--motion-noise", str(f),
                     "--out", str(tmp_path / "d")]) == 0
    truth = json.loads((tmp_path / "d" / "truth.json").read_text())
    assert truth["motion_noise"]["name"] == "bench_step" and truth["motion_noise"]["departure_step"][0] == 1e-3
