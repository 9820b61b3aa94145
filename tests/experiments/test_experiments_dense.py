"""Dense outage protocol (imunoise.experiments.dense), GNSS regimes and the evidence CLI."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from conftest import REPO
from imunoise.errors import ImunoiseError, ModelError
from imunoise.experiments import dense
from imunoise.experiments.common import load_real, repo_data_dir, run_filter
from imunoise.experiments.gnss_regimes import GnssRegime, parse_gnss
from imunoise.io.kfgins import GnssData
from imunoise.nav.earth import radii
from imunoise.nav.metrics import nav_errors
from imunoise.online import OnlineNavigator


def test_parse_outages_and_gnss(tmp_path):
    kind, spec = dense.parse_outages("dense:60:20")
    assert kind == "dense" and spec == dense.DenseSpec(60.0, 20.0, 60.0)
    assert dense.parse_outages("dense:30:10:45")[1] == dense.DenseSpec(30.0, 10.0, 45.0)
    assert dense.parse_outages("4") == ("count", 4)
    f = tmp_path / "o.txt"
    f.write_text("100 60\n")
    assert dense.parse_outages(str(f)) == ("file", f)
    for bad in ("dense:0:20", "dense:a:b", str(tmp_path / "missing.txt")):
        with pytest.raises(ImunoiseError):
            dense.parse_outages(bad)
    assert parse_gnss("rtk") == GnssRegime()
    g = parse_gnss("noise:1.5,3,1")
    assert (g.sigma_h, g.sigma_v, g.rate_hz, g.tau_s) == (1.5, 3.0, 1.0, 0.0) and g.label == "noise:1.5,3,1"
    assert parse_gnss("noise:1,2,,30").tau_s == 30.0
    for bad in ("noise:1", "noise:-1,2", "noise:1,2,0", "gps"):
        with pytest.raises(ImunoiseError):
            parse_gnss(bad)
    assert dense.parse_pairs("gmwm/av, gmwm/em") == [("gmwm", "av"), ("gmwm", "em")]
    with pytest.raises(ImunoiseError):
        dense.parse_pairs("gmwm-av")


def _fixes(n, rate):
    t = 1000.0 + np.arange(n) / rate
    llh = np.column_stack([np.full(n, 0.6), np.full(n, 0.2), np.full(n, 100.0)])
    return GnssData(t=t, llh=llh, sigma_ned=np.full((n, 3), 0.02))


def _ned_noise(orig, noisy, keep):
    llh0 = orig.llh[keep]
    rm, rn = radii(llh0[:, 0])
    dn = (noisy.llh[:, 0] - llh0[:, 0]) * (rm + llh0[:, 2])
    de = (noisy.llh[:, 1] - llh0[:, 1]) * (rn + llh0[:, 2]) * np.cos(llh0[:, 0])
    dd = -(noisy.llh[:, 2] - llh0[:, 2])
    return np.column_stack([dn, de, dd])


def test_white_noise_regime_has_the_requested_sigma_and_rate():
    g = _fixes(40000, 4.0)
    reg = parse_gnss("noise:1.5,3,1")
    a = reg.apply(g, seed=3)
    assert len(a) == 10000 and np.allclose(np.diff(a.t), 1.0)  # 4 Hz thinned to 1 Hz
    e = _ned_noise(g, a, np.arange(0, 40000, 4))
    assert np.std(e, axis=0) == pytest.approx([1.5, 1.5, 3.0], rel=0.03)
    assert abs(np.corrcoef(e[1:, 0], e[:-1, 0])[0, 1]) < 0.03  # white
    # the fixes' own σ (0.02 m) and the added σ combine as independent errors
    assert np.allclose(a.sigma_ned, np.sqrt(np.array([1.5, 1.5, 3.0]) ** 2 + 0.02 ** 2), rtol=0, atol=1e-12)
    assert np.array_equal(reg.apply(g, seed=3).llh, a.llh) and not np.array_equal(reg.apply(g, seed=4).llh, a.llh)
    assert GnssRegime().apply(g) is g


def test_noise_regime_counts_the_noise_the_fixes_already_carry():
    # simulated fixes with 1 / 1 / 2 m of their own: noise:1.5,3 makes them 1.80 / 1.80 / 3.61 m, and says so
    g = _fixes(200, 1.0)
    g = type(g)(t=g.t, llh=g.llh, sigma_ned=np.tile([1.0, 1.0, 2.0], (len(g), 1)))
    a = parse_gnss("noise:1.5,3").apply(g, seed=0)
    assert np.allclose(a.sigma_ned, [math.sqrt(3.25), math.sqrt(3.25), math.sqrt(13.0)])


def test_gauss_markov_regime_has_the_requested_correlation_time():
    g = _fixes(40000, 1.0)
    a = parse_gnss("noise:2,1,,10").apply(g, seed=1)
    e = _ned_noise(g, a, np.arange(40000))
    assert np.std(e, axis=0) == pytest.approx([2.0, 2.0, 1.0], rel=0.06)
    rho = np.mean([np.corrcoef(e[1:, k], e[:-1, k])[0, 1] for k in range(3)])
    assert rho == pytest.approx(math.exp(-0.1), abs=0.01)  # lag 1 s, τ = 10 s


@pytest.fixture(scope="module")
def short_drive():
    """The shipped drive cut to its first 200 s (the initial 29 s stop, then driving)."""
    manifest = REPO / "data" / "drive_0708" / "dataset.json"
    if not manifest.exists():  # only a missing file skips: a reader error must fail
        pytest.skip(f"the shipped drive is absent: {manifest.relative_to(REPO)}")
    sc = load_real(repo_data_dir())
    t1 = sc.init.t + 200.0
    sc.imu = sc.imu.slice(sc.imu.t[0], t1)
    sc.gnss = sc.gnss.slice(sc.gnss.t[0], t1)
    return sc


def test_dense_windows_follow_the_protocol(short_drive):
    sc = short_drive
    w = dense.dense_windows(sc, dense.DenseSpec(60, 20, 60))
    starts = np.array([s for s, _ in w])
    assert starts[0] == pytest.approx(sc.init.t + 60) and np.allclose(np.diff(starts), 20.0)
    assert starts[-1] + 60 <= sc.imu.t[-1] - dense.BRANCH_MARGIN_S
    # a gap of the recorded fixes removes the windows whose lead contains it
    gap = (sc.init.t + 100.0, 5.0)
    sc2 = replace(sc, gnss=sc.gnss.without([gap]))
    w2 = dense.dense_windows(sc2, dense.DenseSpec(60, 20, 60))
    assert [x for x in w if not (x[0] - 60 < gap[0] + gap[1] and gap[0] < x[0])] == w2


def test_branch_equals_a_run_without_the_windows_gnss(short_drive):
    """One aided run with a branch per window = a full run with that window's GNSS removed (to 1e-9 m)."""
    sc = short_drive
    w = (sc.init.t + 100.0, 60.0)
    cfg, models, upd = dense.method_setup("plain", sc)
    r = dense.run_windows(sc, cfg, sc.gnss, [w, (w[0] + 20.0, 30.0)], initial_models=models)
    f = run_filter(sc, cfg, initial_models=models, windows=[w])
    ref = dense.window_metrics(nav_errors(f.t, f.antenna_llh(sc.lever), f.vel_ned, f.euler, sc.ref), *w)
    got = r["windows"][0]
    assert ref["drift"] > 10.0  # a real outage, not a trivial zero
    assert got["drift"] == pytest.approx(ref["drift"], abs=1e-9)
    assert got["rms"] == pytest.approx(ref["rms"], abs=1e-9)
    assert got["aided_rms"] < 0.2  # the aided run over the same span (RTK)
    # an online baseline (static variance refitted at each stop) branches with its refit state
    cfg, models, upd = dense.method_setup("static_var", sc)
    r1 = dense.run_windows(sc, cfg, sc.gnss, [w], initial_models=models, updater=upd)
    cfg, models, upd = dense.method_setup("static_var", sc)
    r2 = dense.run_windows(sc, cfg, sc.gnss.without([w]), [w], initial_models=models, updater=upd)
    assert r1["windows"][0]["rms"] == pytest.approx(r2["windows"][0]["aided_rms"], abs=1e-9)
    assert r1["windows"][0]["rms"] != pytest.approx(got["rms"], abs=1e-6)  # the model did change


def test_static_var_model_is_the_variance_as_white_noise():
    rng = np.random.default_rng(0)
    segs = [rng.normal(5.0, 2.0, (4000, 6)), rng.normal(-3.0, 2.0, (3000, 6))]
    models = dense.static_var_models(segs)
    for m in models:
        assert str(m).startswith("WN") and len(m.components) == 1
        assert m.components[0].values[0] == pytest.approx(4.0, rel=0.05)  # segment means removed


@pytest.mark.slow
def test_cli_evidence_on_two_simulated_drives(tmp_path):
    from imunoise.cli import main

    out = tmp_path / "ev"
    rc = main(["experiment", "online", "--sim", "--seeds", "2", "--duration", "200", "--stops", "1",
               "--outages", "dense:30:30:60", "--methods", "plain,static_var", "--pairs", "plain/static_var",
               "--workers", "1", "--bootstrap", "200", "--latency", "0.5", "--out", str(out)])
    assert rc == 0
    res = json.loads((out / "results.json").read_text())
    assert res["latency_s"] == 0.5
    keys = {"method", "baseline", "metric", "ratio", "ci", "n_windows", "n_drives"}
    assert res["paired"] and all(keys <= set(e) for e in res["paired"])
    got = {(e["method"], e["baseline"], e["metric"]) for e in res["paired"]}
    for m in ("drift", "rms", "aided_rms"):
        assert {("static_var", "plain", m), ("plain", "static_var", m)} <= got
    e = next(e for e in res["paired"] if e["metric"] == "drift" and e["method"] == "static_var")
    inv = next(e for e in res["paired"] if e["metric"] == "drift" and e["method"] == "plain")
    assert inv["ratio"] == pytest.approx(1.0 / e["ratio"], rel=1e-12)  # log-ratios change sign
    assert e["n_drives"] == 2 and e["n_windows"] == res["n_windows"] and e["ci"][0] <= e["ratio"] <= e["ci"][1]
    md = (out / "report.md").read_text()
    assert md.index("Paired ratios") < md.index("Paper-style view")
    assert md.index("Paired ratios") < md.index("paired_drift.png") < md.index("Paper-style view")


@pytest.mark.slow
def test_fixed_latency_puts_every_model_in_effect_at_stop_end_plus_latency(short_drive):
    """With ``latency`` fixed the hot-swap moments do not depend on the machine: every accepted model takes
    effect exactly ``latency`` s after its stop, and a second run repeats the first to the bit."""
    from imunoise.online import OnlineConfig

    sc = short_drive
    runs = []
    for _ in range(2):
        sc.extra.pop("job_cache", None)  # recompute the fits: their measured compute times differ run to run
        cfg, models, upd = dense.method_setup("gmwm", sc, OnlineConfig(latency=1.25))
        assert cfg.latency == 1.25 and cfg.modelling
        runs.append(dense.run_windows(sc, cfg, sc.gnss, [(sc.init.t + 120.0, 30.0)], initial_models=models,
                                      updater=upd, keep=True))
    ups = [u for u in runs[0]["_full"].updates if u.t_effect is not None]
    assert ups and all(sum(u.elapsed_s) > 0 for u in ups)
    assert all(u.t_effect == u.t_stop + 1.25 for u in ups)
    assert [u.t_effect for u in runs[1]["_full"].updates] == [u.t_effect for u in runs[0]["_full"].updates]
    assert runs[1]["windows"] == runs[0]["windows"]


@pytest.mark.parametrize("args, msg", [(["online", "--latency", "-1"], "argument --latency: must be"),
                                        (["denial", "--latency", "1"], "belongs to the online experiment")])
def test_cli_latency_is_checked_before_anything_is_written(tmp_path, capsys, args, msg):
    from imunoise.cli import main

    out = tmp_path / "never"
    try:
        code = main(["experiment", *args, "--sim", "--seeds", "1", "--out", str(out)])
    except SystemExit as e:  # a value refused while the arguments are parsed (argparse's own exit 2)
        code = e.code
    assert code == 2
    assert msg in capsys.readouterr().err and not out.exists()


def test_sf_suffix_adds_the_scale_factor_states_to_the_same_method(short_drive):
    """NAME+sf is NAME's noise model in the 21-state filter (scale factors on); everything else equal."""
    from imunoise.cli.experiment import select_methods

    sc = short_drive
    cfg0, models0, _ = dense.method_setup("plain", sc)
    cfg1, models1, _ = dense.method_setup("plain+sf", sc)
    assert not cfg0.ekf.scale_factors and cfg1.ekf.scale_factors
    assert cfg1.with_(ekf=cfg1.ekf.with_(scale_factors=False)) == cfg0 and models1 == models0
    w = [(sc.init.t + 100.0, 60.0)]
    r0 = dense.run_windows(sc, cfg0, sc.gnss, w, initial_models=models0)
    r1 = dense.run_windows(sc, cfg1, sc.gnss, w, initial_models=models1)
    d0, d1 = r0["windows"][0]["drift"], r1["windows"][0]["drift"]
    assert np.isfinite(d1) and d1 != pytest.approx(d0, rel=1e-6)  # the extra states changed the outage
    assert select_methods("online", False, "gmwm,gmwm+sf", evidence=True) == ("gmwm", "gmwm+sf")
    with pytest.raises(ModelError, match="unknown method"):
        select_methods("online", False, "bogus+sf", evidence=True)


class _NoUpdate:
    """An updater that does nothing: run_windows then takes its per-sample path."""

    def shared(self) -> tuple:
        return ()

    def step(self, nav) -> None:
        pass


@pytest.mark.parametrize("method", ["plain", "gmwm"])
def test_chunked_windows_equal_the_per_sample_run_to_the_bit(short_drive, method):
    """The aided run and its branches pushed in chunks give the per-sample values exactly (two windows
    opening at the same sample, one overlapping the next, one past the end of the record), although the chunked
    branches stop at the sample of the window's last reference epoch and are read from the navigator's stored
    epochs instead of its finished result, and plain's chunked run drops the stop guard (it models nothing)
    while the per-sample run (an updater) keeps it."""
    sc = short_drive
    s0 = sc.init.t + 60.0
    windows = [(s0 + 20.0, 60.0), (s0, 60.0), (s0 + 1e-4, 30.0), (float(sc.imu.t[-1]) + 5.0, 10.0)]
    cfg, models, _ = dense.method_setup(method, sc, cache={})
    fast = dense.run_windows(sc, cfg, sc.gnss, windows, initial_models=models)
    cfg, models, _ = dense.method_setup(method, sc, cache={})
    slow = dense.run_windows(sc, cfg, sc.gnss, windows, initial_models=models, updater=_NoUpdate())
    assert fast == slow
    assert fast["windows"][1]["drift"] > 1.0 and fast["windows"][3]["drift"] is None


def test_errors_from_the_stored_epochs_equal_the_finished_results(short_drive):
    """The aided run's and a branch's errors read from the navigator's stored epochs (only those the error
    computation uses) equal those of the finished result, to the bit (the reference here is off the IMU grid)."""
    from imunoise.experiments.window_errors import branch_errors, stored_errors

    sc = short_drive
    w = [(sc.init.t + 70.0, 60.0), (sc.init.t + 90.0, 30.0)]
    cfg, models, _ = dense.method_setup("plain", sc, cache={})
    kept = dense.run_windows(sc, cfg, sc.gnss, w, initial_models=models, keep=True)  # errors of the result
    cfg, models, _ = dense.method_setup("plain", sc, cache={})
    got = dense.run_windows(sc, cfg, sc.gnss, w, initial_models=models)  # errors of the stored epochs
    assert got["windows"] == kept["windows"]
    assert (got["horizontal_rms_m"], got["vertical_rms_m"]) == (kept["horizontal_rms_m"], kept["vertical_rms_m"])
    # a branch: its copy of the first epoch just before the start, as branch_errors makes it
    cfg, models, _ = dense.method_setup("plain", sc, cache={})
    nav = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate, initial_models=models)
    t, (dth, dv) = sc.imu.t, sc.imu.increments()
    i = int(np.searchsorted(t, w[0][0]))
    nav.push_chunk(t[:i], dth[:i], dv[:i], sc.gnss.t[sc.gnss.t < w[0][0]], sc.gnss.llh[sc.gnss.t < w[0][0]],
                   sc.gnss.sigma_ned[sc.gnss.t < w[0][0]])
    br = nav.fork()[0]
    br.push_chunk(t[i:i + 3000], dth[i:i + 3000], dv[i:i + 3000])
    a = stored_errors(br, sc, w[0][0])
    b = branch_errors(br.finish(), sc, w[0][0])
    assert a.t.size == b.t.size > 100
    assert np.array_equal(a.t, b.t) and np.array_equal(a.ned, b.ned) and np.array_equal(a.vel, b.vel)
    assert np.array_equal(a.att, b.att, equal_nan=True)
