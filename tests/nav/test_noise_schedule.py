"""The law-aware filter's process noise (imunoise.nav.noise_schedule, issue 21 §2): what it injects over a drive
is what the law's schedule says, the moving Gauss–Markov is frozen at stops, the departure bump is exact."""

from __future__ import annotations

import json
import math
from importlib import resources

import numpy as np
import pytest

from imunoise.experiments.common import simulate_scenario
from imunoise.experiments.oracle_law import _fixes, law_filter, law_models
from imunoise.nav.noise_schedule import run_pieces
from imunoise.nav.state import N_NAV
from imunoise.nav.step_filter import new_outputs
from imunoise.online import OnlineConfig

GM_SIGMA, GM_TAU, STEP = 6e-4, 40.0, 7e-4
# the online engine's angular-rate gate (conservative noise in sharp turns, which oracle_law shares with the
# online methods) is off here: these tests measure what the law's schedule alone injects
NO_GATE = OnlineConfig(gate=False)


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    """A short drive under the default law plus every time-structured term (moving GM, departure step, warm-up)."""
    law = json.loads(resources.files("imunoise.sim").joinpath("laws/drive0708.json").read_text())
    law.update({"name": "all_terms", "moving_gm": {"sigma": [GM_SIGMA] * 3 + [0.0] * 3, "tau_s": [GM_TAU] * 6},
                "departure_step": [STEP] * 3 + [0.0] * 3,
                "warmup": {"amplitude": [1e-3, -5e-4, 2e-4, 0.02, 0.0, -0.01], "tau_s": 300.0}})
    path = tmp_path_factory.mktemp("law") / "all_terms.json"
    path.write_text(json.dumps(law))
    sc = simulate_scenario(5, duration_s=240.0, n_stops=2, n_outages=0, motion_noise=str(path))
    lf = law_filter(sc, base=NO_GATE)
    assert np.any(lf.bump) and np.any(~lf.moving[1:]) and np.all(lf.noise.gm_index[:3] >= 0)
    # open loop (no fixes): the model block of P then evolves as Φ_m P Φ_mᵀ + Q_m alone
    f = lf.ekf.arrays()
    nm = lf.ekf.layout.nm
    f.P[N_NAV:, N_NAV:] = 0.0
    log = []

    def before(k):
        P0 = f.P.copy()
        m = lf.before_piece(f, k)
        log.append((k, P0, f.P.copy(), m))
        return m

    n = lf.imu.t.size
    empty = _fixes(sc.gnss, lf.ekf, keep=lambda g: g < -1.0)
    bounds = [*map(int, lf.bounds), n - 1]
    run_pieces(lf.ekf, lf.imu, f, empty, new_outputs(n, store_cov=False, has_sf=False), bounds, before)
    log.append((n - 1, f.P.copy(), f.P.copy(), None))
    assert nm == f.P.shape[0] - N_NAV
    return sc, lf, log


def test_injected_noise_integrates_to_the_schedule(drive):
    sc, lf, log = drive
    sched = sc.extra["law_schedule"]
    i0 = int(np.searchsorted(sc.imu.t, sc.init.t, side="right")) - 1
    steps = slice(i0 + 1, i0 + lf.imu.t.size)  # the schedule's samples of the filter's steps
    dt = lf.ekf.dt_nom
    rw = [sum(c.values[0] for c in m.components if c.kind == "RW") for m in law_models(sc)]
    b = lf.noise.bias_index + N_NAV
    P_end = log[-1][1]
    dep = set(int(d) for d in sched.departure_index) & set(range(steps.start, steps.stop))
    for a in range(6):
        want = (rw[a] * np.sum(sched.bias_var_scale[steps, a]) + sched.warmup_rw_q[a] * dt * (lf.imu.t.size - 1)
                + len(dep) * sched.step_var[a])
        assert want > 0
        assert P_end[b[a], b[a]] == pytest.approx(want, rel=1e-12)
    # white PSD: Σ over pieces psd·mean(m²)·(piece length) = Σ_k psd·m²[k]·Δt
    # (the folded short-AR1 part of the PSD, bias noise, takes m_b²)
    folded = lf.noise.bias_psd
    assert folded[0] > 0
    white = lf.noise.base.wpsd - folded
    got = sum(m.wpsd * (log[i + 1][0] - k) * dt for i, (k, _, _, m) in enumerate(log[:-1]))
    want = (white * np.sum(sched.white_var_scale[steps], axis=0)
            + folded * np.sum(sched.bias_var_scale[steps], axis=0)) * dt
    np.testing.assert_allclose(got, want, rtol=1e-12)


def test_moving_gm_frozen_at_stops_and_gm_while_moving(drive):
    _, lf, log = drive
    phi = math.exp(-lf.ekf.dt_nom / GM_TAU)
    n_static = n_moving = 0
    for i, (_, _, after, m) in enumerate(log[:-1]):
        P_next = log[i + 1][1]
        for g in lf.noise.gm_index[:3]:
            G = g + N_NAV
            if not lf.moving[i]:
                assert P_next[G, G] == after[G, G]  # frozen: not a bit of change
                assert m.phi_pow[5][g, g] == 1.0 and m.q_pow[5][g, g] == 0.0
                n_static += 1
            else:
                # one step: φ = e^{−Δt/τ}, q = σ²(1 − φ²), unscaled by the bias multiplier
                assert m.phi_pow[1][g, g] == pytest.approx(phi, rel=1e-14)
                assert m.q_pow[1][g, g] == pytest.approx(GM_SIGMA ** 2 * (1 - phi * phi), rel=1e-12)
                assert after[G, G] < P_next[G, G] < GM_SIGMA ** 2
                n_moving += 1
    assert n_static > 0 and n_moving > 0


def test_departure_bump_exact(drive):
    _, lf, log = drive
    bumps = [(before, after) for k, before, after, _ in log[:-1] if lf.bump[list(lf.bounds).index(k)]]
    assert bumps
    b = lf.noise.bias_index + N_NAV
    for before, after in bumps:
        want = before.copy()
        want[b[:3], b[:3]] += STEP ** 2  # the bias variances of the gyros, nothing else
        np.testing.assert_array_equal(after, want)


@pytest.fixture(scope="module")
def accel_drive():
    """A short drive under the shipped accel_moving_gm law, the filter run open loop from a zero model covariance."""
    sc = simulate_scenario(7, duration_s=240.0, n_stops=2, n_outages=0, motion_noise="accel_moving_gm")
    lf = law_filter(sc, base=NO_GATE)
    f = lf.ekf.arrays()
    P0 = f.P.copy()
    f.P[N_NAV:, N_NAV:] = 0.0
    ends = []

    def before(k):
        ends.append((k, f.P.copy()))
        return lf.before_piece(f, k)

    n = lf.imu.t.size
    run_pieces(lf.ekf, lf.imu, f, _fixes(sc.gnss, lf.ekf, keep=lambda g: g < -1.0),
               new_outputs(n, store_cov=False, has_sf=False), [*map(int, lf.bounds), n - 1], before)
    ends.append((n - 1, f.P.copy()))
    return sc, lf, ends, P0


def test_accel_moving_gm_grows_only_while_moving_to_its_sigma(accel_drive):
    """The accelerometer moving GM: P_gm after the drive is σ²(1 − φ^{2·N_moving}) exactly (N_moving the filter's
    moving steps; stops add nothing), on the simulator's own moving flags, with its steady state σ² = 0.02²."""
    sc, lf, ends, P0 = accel_drive
    sched = sc.extra["law_schedule"]
    i0 = int(np.searchsorted(sc.imu.t, sc.init.t, side="right")) - 1
    n = lf.imu.t.size
    # the filter's moving flag per step into k is the simulator's: schedule sample k + i0 is moving
    np.testing.assert_array_equal(sched.moving, ~np.asarray(sc.static_truth, dtype=bool))
    moving_steps = int(np.sum(sched.moving[i0 + 1 : i0 + n]))
    assert 0 < moving_steps < n - 1
    sigma, tau = 0.02, 120.0
    phi = math.exp(-lf.ekf.dt_nom / tau)
    g = lf.noise.gm_index
    assert np.all(g[:3] == -1) and np.all(g[3:] >= 0)
    grown = []
    for i, ((k, P), (_, P_next)) in enumerate(zip(ends[:-1], ends[1:])):
        G = g[3:] + N_NAV
        d = np.diag(P_next)[G] - np.diag(P)[G]
        if lf.moving[i]:
            assert np.all(d > 0)
            grown.append(k)
        else:
            assert np.all(d == 0.0)  # frozen at the stop
    assert grown
    # the kernel propagates every cov_every = 5 samples as P ← Φ(P + Q/2)Φᵀ + Q/2 with the exact 5-step Q, which
    # puts the steady state at σ²(1 + φ^10)/2 = σ²(1 − 4.2e-4): hence 1e-3, not 1e-9 (one lost step would be 1.4e-4)
    for G in g[3:] + N_NAV:
        assert ends[-1][1][G, G] == pytest.approx(sigma ** 2 * (1 - phi ** (2 * moving_steps)), rel=1e-3)
        assert ends[-1][1][G, G] < sigma ** 2 * (1 - phi ** (2 * moving_steps))
        assert P0[G, G] == pytest.approx(sigma ** 2, rel=1e-12)  # its initial covariance: stationary


def test_oracle_carries_the_accel_moving_gm_always_on():
    """Why oracle_law gains little over oracle on accel_moving_gm: the constant model of ``oracle`` already has the
    same Gauss–Markov (σ, τ) on every accelerometer axis, evolving all the time; only the freeze at stops differs."""
    from imunoise.imu import AXES

    sc = simulate_scenario(7, duration_s=200.0, n_stops=1, n_outages=0, motion_noise="accel_moving_gm")
    phi = math.exp(-1.0 / (120.0 * sc.rate))
    for ax in AXES:
        static = {c.values for c in sc.extra["static_models"][ax].components if c.kind == "AR1"}
        extra = [c.values for c in sc.truth_models[ax].components if c.kind == "AR1" and c.values not in static]
        if ax.startswith("gyro"):
            assert extra == []
        else:
            assert len(extra) == 1
            assert extra[0][0] == pytest.approx(phi, rel=1e-12)
            assert extra[0][1] == pytest.approx(0.02 ** 2 * (1 - phi * phi), rel=1e-9)
