"""``oracle_law`` (issue 21 §2) on the default law: the filter told the law per sample drifts least, the
constant-model oracle next, the plain filter most (mean end-of-window drift over the dense windows).

The three rows run through the same batch path here (imunoise.experiments.oracle_law.run_windows_law with the
models of each method), on four 5-minute development drives (one drive can rank them otherwise: seed 1000 alone has
oracle_law 161 m, oracle 149 m), to keep the test fast; the 10-drive check (10-minute drives, seeds 1000–1009) is
``python benchmarks/bench_oracle_law.py drive0708 --seed0 1000``."""

from __future__ import annotations

import numpy as np
import pytest

from imunoise.experiments import dense
from imunoise.experiments.common import simulate_scenario
from imunoise.experiments.online_exp import method_config
from imunoise.experiments.oracle_law import run_windows_law
from imunoise.nav.defaults import default_axis_models


def _mean_drift(res: dict) -> float:
    return float(np.mean([w["drift"] for w in res["windows"] if w["drift"] is not None]))


@pytest.mark.slow  # evidence on four simulated drives
def test_oracle_law_beats_oracle_beats_plain_on_the_default_law():
    rows = []
    for seed in (1000, 1001, 1002, 1003):
        sc = simulate_scenario(seed, duration_s=300.0, n_stops=2, n_outages=0)
        assert sc.extra["motion_noise"] and sc.extra["law_schedule"] is not None
        windows = dense.dense_windows(sc, dense.parse_outages("dense:60:20")[1])
        assert len(windows) >= 8
        cfg, oracle_models = method_config("oracle", sc)
        plain = default_axis_models(sc.rate, cfg.ekf.fallback)
        law = run_windows_law(sc, sc.gnss, windows)
        rows.append([_mean_drift(law), _mean_drift(run_windows_law(sc, sc.gnss, windows, models=oracle_models)),
                     _mean_drift(run_windows_law(sc, sc.gnss, windows, models=plain))])
        if seed == 1000:  # the dense experiment's oracle_law row is this path
            assert _mean_drift(dense.evaluate_method(sc, "oracle_law", sc.gnss, windows)) == rows[-1][0]
    law, oracle, plain = np.mean(rows, axis=0)
    assert law <= oracle <= plain, rows


def test_oracle_law_in_the_online_monte_carlo():
    from imunoise.experiments.online_exp import MC_METHODS, _sim_job_clean

    assert MC_METHODS.index("oracle_law") == MC_METHODS.index("oracle") - 1  # the ceiling, then the constant oracle
    r = _sim_job_clean(1000, ("oracle_law",), {"duration_s": 300.0, "n_stops": 2, "n_outages": 2}, -1, None)
    m = r["methods"]["oracle_law"]
    assert len(m["outage_end_horizontal_m"]) == 2 and all(0 < x < 1000 for x in m["outage_end_horizontal_m"])
    assert m["mean_outage_end_horizontal_m"] == np.mean(m["outage_end_horizontal_m"])
    assert m["horizontal_rms_m"] < 3.0  # aided by meter-level fixes throughout


def test_oracle_law_is_the_oracle_when_the_law_adds_nothing():
    """Under the law ``none`` the two oracles are one filter (the same models, the online engine's 30 °/s
    angular-rate gate on both), so the only difference ``oracle_law`` can make elsewhere is the law."""
    from imunoise.experiments.oracle_law import law_filter
    from imunoise.online import OnlineConfig

    sc = simulate_scenario(1004, duration_s=300.0, n_stops=2, n_outages=0, motion_noise="none")
    windows = dense.dense_windows(sc, dense.parse_outages("dense:60:20")[1])
    base = OnlineConfig(latency=1.0)
    assert np.any(law_filter(sc, base=base).imu.gate)  # corners of 35-50 °/s open the gate
    o = dense.evaluate_method(sc, "oracle", sc.gnss, windows, base=base)["windows"]
    law = dense.evaluate_method(sc, "oracle_law", sc.gnss, windows, base=base)["windows"]
    for a, b in zip(law, o, strict=True):
        assert a["drift"] == pytest.approx(b["drift"], rel=1e-4)
    assert not np.any(law_filter(sc, base=base.with_(gate=False)).imu.gate)


def test_the_moving_state_is_the_appended_one_beside_a_static_ar1_of_the_same_tau():
    """The oracle finds each axis' moving Gauss–Markov state by the component it appended, not by its φ: with a
    static AR1 of the same τ (the same φ) on every axis the law moves, the schedule's moving state is the one that
    starts with the law's σ² and is frozen at stops, the static one keeps evolving."""
    import math
    from dataclasses import replace

    from imunoise.experiments.oracle_law import law_filter, law_states
    from imunoise.imu import AXES
    from imunoise.nav.state import N_NAV
    from imunoise.noise.model import Model
    from imunoise.noise.processes import AR1

    sc = simulate_scenario(5, duration_s=150.0, n_stops=1, n_outages=0, static_s=20.0,
                           motion_noise="gyro_moving_gm")
    sched = sc.extra["law_schedule"]
    axes = [a for a in range(6) if sched.gm_sigma[a] > 0]
    assert axes  # the law moves a GM on the gyros
    static = dict(sc.extra["static_models"])
    static_var = {}
    for a in axes:
        m = static[AXES[a]]  # the truth: parameters per IMU sample, taken at sc.rate by the oracle's mapping
        phi = math.exp(-1.0 / (float(sched.gm_tau_s[a]) * sc.rate))
        static_var[a] = 0.3 * float(sched.gm_sigma[a]) ** 2  # not the law's σ²: the two states are told apart
        static[AXES[a]] = Model([*m.components, AR1(phi=phi, sigma2=static_var[a] * (1 - phi * phi))], m.freq)
    sc = replace(sc, extra={**sc.extra, "static_models": static})
    models, gm_index = law_states(sc)
    lf = law_filter(sc)
    labels, P = lf.ekf.layout.labels, np.asarray(lf.ekf.P)
    assert [k >= 0 for k in gm_index] == [a in axes for a in range(6)]
    for a in axes:
        phi = math.exp(-1.0 / (float(sched.gm_tau_s[a]) * sc.rate))
        same = [i for i, c in enumerate(models[a].components) if c.kind == "AR1" and c.values[0] == phi]
        assert len(same) == 2 and gm_index[a] in same  # the ambiguous case, resolved by the component itself
        g = int(lf.noise.gm_index[a])
        s = [i for i, lab in enumerate(labels) if lab.startswith(f"{AXES[a]}.AR1_")
             and i != g and lf.ekf.layout.phi_pow[1, i, i] == lf.ekf.layout.phi_pow[1, g, g]]
        assert len(s) == 1
        sig2 = float(sched.gm_sigma[a]) ** 2
        np.testing.assert_allclose(P[N_NAV + g, N_NAV + g], sig2, rtol=1e-12)
        np.testing.assert_allclose(P[N_NAV + s[0], N_NAV + s[0]], static_var[a], rtol=1e-12)
        assert np.all(lf.noise.phi_frozen[1:, g, g] == 1.0) and np.all(lf.noise.q_frozen[:, g, g] == 0.0)
        assert np.all(lf.noise.phi_frozen[1:, s[0], s[0]] < 1.0)
    assert np.all(lf.noise.gm_index[[a for a in range(6) if a not in axes]] == -1)
