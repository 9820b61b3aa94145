"""Allan-variance baseline (docs/guide/theory.rst, 'Baselines'): AV identity, dense grid, IEEE reading, equivalent
model, CLI."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from imunoise.cli import main as cli_main
from imunoise.errors import DataError, FitError
from imunoise.noise.allan import (
    BI_FACTOR,
    AllanReading,
    allan_fit,
    allan_variance,
    read_allan,
    reading_model,
)
from imunoise.noise.model import Model
from imunoise.noise.wv import wavelet_variance


def test_dense_grid_equals_octave_identity():
    x = np.random.default_rng(0).normal(size=5000).cumsum() * 1e-3 + np.random.default_rng(1).normal(size=5000)
    dense = allan_variance(x, freq=50.0, grid="dense", points_per_decade=40)
    octave = allan_variance(x, freq=50.0, grid="octave")
    common = np.intersect1d(dense.tau, octave.tau)
    assert common.size >= 6
    for t in common:
        a = dense.avar[dense.tau == t][0]
        b = octave.avar[octave.tau == t][0]
        assert a == pytest.approx(b, rel=1e-9)
    # segments are pooled without crossing junctions, like the WV
    segs = [x[:2000], x[2000:]]
    d2 = allan_variance(segs, freq=50.0, grid="dense", points_per_decade=40)
    w2 = wavelet_variance(segs, freq=50.0)
    m = w2.scales / 2 / 50.0
    for t, v in zip(m, 2 * w2.variance):
        if t in d2.tau:
            assert d2.avar[d2.tau == t][0] == pytest.approx(v, rel=1e-9)


def test_dense_matches_allantools():
    import allantools
    x = np.random.default_rng(3).normal(size=4000)
    av = allan_variance(x, freq=10.0, grid="dense", points_per_decade=8)
    taus, adev, _, _ = allantools.oadev(x, rate=10.0, data_type="freq", taus=av.tau)
    for t, a in zip(taus, adev):
        assert av.adev[np.isclose(av.tau, t)][0] == pytest.approx(a, rel=1e-9)


def test_reading_model_conversions_are_exact():
    r = AllanReading(N=2e-3, K=3e-5, B=4e-4, T_BI=20.0, Q=1e-5, R=1e-6)
    m = reading_model(r, 200.0)
    c = m.continuous(200.0)
    assert c["WN.noise_density"] == pytest.approx(2e-3)
    assert c["RW.random_walk"] == pytest.approx(3e-5)
    assert c["QN.q_ieee"] == pytest.approx(1e-5)
    assert c["DR.rate_ramp"] == pytest.approx(1e-6)
    assert c["AR1_1.tau_c"] == pytest.approx(20.0)
    assert c["AR1_1.sigma_gm"] == pytest.approx(4e-4)
    with pytest.raises(FitError):
        reading_model(AllanReading(), 100.0)


def test_reading_recovers_white_noise_and_random_walk():
    f = 100.0
    true = Model.parse("WN+RW").with_params({"WN.sigma2": 1e-4, "RW.gamma2": 3e-4 / 1e6})  # crossover 10 s
    c = true.continuous(f)
    fit = allan_fit(true.simulate(2**20, seed=7), freq=f, unit="rad/s")
    a = fit.extra["allan"]
    assert a["N"] == pytest.approx(c["WN.noise_density"], rel=0.03)
    assert a["K"] == pytest.approx(c["RW.random_walk"], rel=0.3)
    lo, hi = a["regions_s"]["N"]
    assert lo <= 1.0 <= hi  # the −½ line is read where it is, at 1 s
    assert a["regions_s"]["K"][0] > 10.0  # the +½ region lies beyond the crossover
    assert fit.method == "av" and fit.model.has("WN") and fit.model.has("RW")
    # B is the lowest AD of the flat region over 0.6643 and T_BI its τ
    av = allan_variance(true.simulate(2**16, seed=1), freq=f)
    rd = read_allan(av)
    assert math.isfinite(rd.B)
    ok = av.dof >= 3
    assert rd.B * BI_FACTOR == pytest.approx(av.adev[av.tau == rd.T_BI][0])
    assert rd.B * BI_FACTOR <= 1.1 * np.sqrt(av.avar[ok]).min()


def test_quantisation_slope_is_found():
    true = Model.parse("WN+QN").with_params({"WN.sigma2": 1e-8, "QN.q2": 1e-4})
    f = 100.0
    fit = allan_fit(true.simulate(2**16, seed=2), freq=f)
    q = fit.extra["allan"]["Q"]
    assert q == pytest.approx(true.continuous(f)["QN.q_ieee"], rel=0.2)


def test_bad_input():
    with pytest.raises(DataError):
        allan_variance(np.array([1.0, np.nan, 2.0, 3.0, 4.0]), freq=1.0, grid="dense")
    with pytest.raises(DataError):
        allan_variance(np.ones(100), freq=0.0)
    with pytest.raises(FitError):
        read_allan(allan_variance(np.random.default_rng(0).normal(size=16), freq=1.0, grid="dense"))


def test_cli_allan(tmp_path, capsys):
    data = tmp_path / "x.csv"
    true = Model.parse("WN+RW").with_params({"WN.sigma2": 1e-4, "RW.gamma2": 1e-9})
    np.savetxt(data, true.simulate(2**15, seed=1))
    out = tmp_path / "av"
    assert cli_main(["allan", str(data), "--freq", "100", "--units", "deg/s", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "−½ line at 1 s" in text and "rad/s" in text
    d = json.loads((out / "model.json").read_text())
    assert d["method"] == "av" and d["unit"] == "rad/s"
    assert (out / "allan.png").stat().st_size > 0
    rows = (out / "allan.csv").read_text().splitlines()
    assert rows[0].startswith("tau_s,") and len(rows) > 20
