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
