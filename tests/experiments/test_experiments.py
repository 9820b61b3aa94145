"""Experiments (docs/guide/theory.rst, 'Experiments'): CIs, Monte Carlo plumbing, result keys, reports, CLI, the shipped
real drive."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy import stats

from conftest import REPO
from imunoise.cli import main
from imunoise.experiments import denial, online_exp
from imunoise.experiments.common import paired_ci, repo_data_dir
from imunoise.experiments.report import write_online_real, write_sim
from imunoise.imu import AXES
from imunoise.online import OnlineConfig

FAST = OnlineConfig(complete="2*AR1 + WN + RW")
SIM = {"duration_s": 240.0, "n_stops": 2, "n_outages": 1, "static_s": 30.0, "stop_range_s": (8.0, 20.0)}
SPEC_KEYS = {"horizontal_rms_m", "vertical_rms_m", "ecef_rms_m", "outage_end_horizontal_m",
             "mean_outage_end_horizontal_m"}


def shipped_drive():
    """``data/drive_0708``; skips only when the checkout lacks the file (a reader error must fail the test)."""
    manifest = REPO / "data" / "drive_0708" / "dataset.json"
    if not manifest.exists():
        pytest.skip(f"the shipped drive is absent: {manifest.relative_to(REPO)}")
    return repo_data_dir()


def test_paired_ci_matches_the_t_interval():
    b = np.array([10.0, 20.0, 30.0, 40.0])
    a = b + np.array([1.0, 2.0, 3.0, 4.0])
    c = paired_ci(a, b)
    se = np.std([1, 2, 3, 4], ddof=1) / 2.0
    tq = stats.t.ppf(0.975, 3)
    assert c["mean_diff"] == pytest.approx(2.5)
    assert c["ci"] == pytest.approx([2.5 - tq * se, 2.5 + tq * se])
    assert c["excludes_zero"]
    # a = 2b exactly: +100 % with a zero-width CI
    d = paired_ci(2 * b, b)
    assert d["rel_pct"] == pytest.approx(100.0) and d["rel_ci_pct"] == pytest.approx([100.0, 100.0])
    # symmetric noise around zero: CI contains 0
    e = paired_ci(b + np.array([1.0, -1.0, 1.0, -1.0]), b)
    assert not e["excludes_zero"]
    assert math.isnan(paired_ci([1.0], [2.0])["mean_diff"])


@pytest.fixture(scope="module")
def mc():
    return online_exp.run_sim([0, 1], methods=("plain", "gmwm"), workers=2, base=FAST, **SIM)


@pytest.mark.slow
def test_sim_monte_carlo_results(mc, tmp_path):
    assert mc["seeds"] == [0, 1]
    for name in ("plain", "gmwm"):
        assert SPEC_KEYS <= set(mc["methods"][name])
        assert len(mc["per_seed"][name]) == 2
        assert len(mc["methods"][name]["outage_end_horizontal_m"]) == 1
    # the mean is the mean of the per-seed values
    per = [r["horizontal_rms_m"] for r in mc["per_seed"]["gmwm"]]
    assert mc["methods"]["gmwm"]["horizontal_rms_m"] == pytest.approx(np.mean(per))
    d = mc["differences"]["gmwm"]["vs_plain"]["mean_outage_end_horizontal_m"]
    diffs = [g["mean_outage_end_horizontal_m"] - p["mean_outage_end_horizontal_m"]
             for g, p in zip(mc["per_seed"]["gmwm"], mc["per_seed"]["plain"])]
    assert d["mean_diff"] == pytest.approx(np.mean(diffs))
    assert mc["timing"]["identification_s"] > 0 and mc["timing"]["refit_s"]
    html = write_sim(mc, tmp_path, title="test")
    assert html.exists() and "<img src='data:image/png;base64," in html.read_text()
    res = json.loads((tmp_path / "results.json").read_text())
    assert set(res["methods"]) == {"plain", "gmwm"} and res["seeds"] == [0, 1]
    assert "timing" in res and "identification_s" in res["timing"]
    for f in ("report.md", "headline.csv", "differences.csv", "outages.csv", "montecarlo.png"):
        assert (tmp_path / f).exists()


@pytest.mark.slow
def test_oracle_is_the_true_model_and_sim_only(real):
    """The oracle method filters with the simulator's true models (same mapping, no floor); real data has none."""
    from imunoise.experiments.common import filter_models, simulate_scenario

    sc = simulate_scenario(0, **SIM)
    cfg, models = online_exp.method_config("oracle", sc)
    assert not cfg.modelling
    truth = [sc.truth_models[ax] for ax in AXES]
    want = filter_models(truth, sc.rate, cfg.with_(floor="none"))
    assert [str(m) for m in models] == [str(m) for m in want]
    assert all(m.params == pytest.approx(w.params) for m, w in zip(models, want))
    # the paper preset's gyro x RW (K = 4.0e-5 rad/s/√s) reaches the filter unchanged
    assert models[0].continuous(sc.rate)["RW.random_walk"] == pytest.approx(3.994e-5, rel=1e-3)
    # the filter's initial bias σ is the simulated turn-on σ (5 mg)
    assert cfg.ekf.sigma_accel_bias0 == pytest.approx(0.05)
    with pytest.raises(ValueError, match="simulated"):
        online_exp.method_config("oracle", real[1])


@pytest.mark.slow
def test_denial_sim_models_and_keys():
    res = denial.run_sim([0], methods=("plain", "av", "gmwm", "gmwm_top3"), workers=1, static_recording_s=600.0,
                         complete="2*AR1 + WN + RW", **SIM)
    assert res["experiment"] == "denial"
    for name in ("plain", "av", "gmwm", "gmwm_top3"):
        assert SPEC_KEYS <= set(res["methods"][name])
    models = res["models_per_seed"][0]
    assert len(models["gmwm"]) == len(models["gmwm_top3"]) == len(AXES)
    # the 3rd of the GOF ranking is another structure than its best, on every axis
    assert all(best != third for best, third in zip(models["gmwm"], models["gmwm_top3"])), models
    assert all(m.startswith("AR1") or "WN" in m or "RW" in m for m in models["av"])


@pytest.fixture(scope="module")
def real():
    return online_exp.run_real(str(shipped_drive()), methods=("plain", "gmwm"), workers=2, base=FAST)


@pytest.mark.slow
def test_real_drive_online(real, tmp_path):
    res, sc = real
    assert len(sc.windows) == 5
    assert res["kfgins_outage_end_horizontal_m"] == [335.5, 520.9, 42.7, 398.6, 310.8]
    for name in ("plain", "gmwm"):
        m = res["methods"][name]
        assert SPEC_KEYS <= set(m)
        assert len(m["outage_end_horizontal_m"]) == 5 and all(x > 0 for x in m["outage_end_horizontal_m"])
        # full-RTK residuals are centimetres, outage drifts tens to hundreds of metres
        assert m["horizontal_rms_m"] < 0.1 and m["mean_outage_end_horizontal_m"] > 10
    t = res["timing"]
    assert t["identification_s"] > 0 and len(t["refit_s"]) >= 1
    # the first identification happens during the initial stop (before the first outage window)
    ups = res["sections"]["updates"]
    assert ups[0]["kind"] == "identify" and ups[0]["t_effect"] < sc.windows[0][0]
    html = write_online_real(res, sc, tmp_path)
    text = html.read_text()
    assert "KF-GINS" in text and text.count("<img") >= 5
    lines = (tmp_path / "events.jsonl").read_text().splitlines()
    kinds = {json.loads(x)["event"] for x in lines}
    assert {"start", "stop_start", "stop_end", "identified", "refit", "swap", "gate_open", "end"} <= kinds


@pytest.mark.slow
def test_cli_experiment_sim(tmp_path):
    out = tmp_path / "exp"
    rc = main(["experiment", "online", "--sim", "--seeds", "1", "--duration", "240", "--stops", "2", "--outages",
               "1", "--methods", "plain", "--workers", "1", "--out", str(out)])
    assert rc == 0
    res = json.loads((out / "results.json").read_text())
    assert set(res["methods"]) == {"plain"} and (out / "report.html").exists()


def test_cli_rejects_unknown_method(tmp_path, capsys):
    rc = main(["experiment", "online", "--sim", "--seeds", "1", "--methods", "kalman", "--out", str(tmp_path)])
    assert rc == 2
    assert "unknown method" in capsys.readouterr().err


@pytest.mark.slow
def test_cli_online_on_the_shipped_drive(tmp_path):
    folder = shipped_drive()
    out = tmp_path / "on"
    rc = main(["online", "--data", str(folder), "--latency", "0", "--out", str(out)])
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    for k in ("horizontal_rms_m", "horizontal_p95_m", "horizontal_max_m", "vertical_rms_m", "velocity_rms_mps",
              "ecef_rms_m", "outages", "elapsed_s", "realtime_factor"):
        assert k in m
    assert m["timing"]["identification_s"] > 0
    assert (out / "events.jsonl").exists() and (out / "model.json").exists()
    model = json.loads((out / "model.json").read_text())
    assert set(model["axes"]) == {"gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"}
