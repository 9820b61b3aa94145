"""Fit quality against the data (:mod:`imunoise.noise.fitting.quality`) and the ``--export`` gate built on it
(:mod:`imunoise.cli.export_gate`): the band rule, the exported pair against the data's Allan variance, the
richer-candidate retry, and the one-line refusal / ``--force`` warning written into the files."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from imunoise.cli import main
from imunoise.cli.export_gate import with_warnings
from imunoise.export import read_export
from imunoise.noise.fitting.quality import BAND_RUN, BAND_TOLERANCE, band_check, pair_check, within_band
from imunoise.noise.model import as_model
from imunoise.noise.selection import select_model
from imunoise.noise.wv import WaveletVariance, wavelet_variance

F = 100.0


def unit_band(J: int) -> WaveletVariance:
    """A WV of ν̂ = 1 with the band [0.5, 2] on J levels."""
    one = np.ones(J)
    return WaveletVariance(2.0 ** np.arange(1, J + 1), one, 0.5 * one, 2.0 * one, np.full(J, 1000), np.eye(J), F)


@pytest.mark.parametrize(
    ("J", "outside", "refused"),
    [
        (12, [3, 4], False),  # two adjacent levels: happens to right models
        (12, [3, 4, 5], True),  # three consecutive: a range of scales
        (12, [0, 4, 8], True),  # 25 % of 12 levels
        (12, [0, 8], False),
        (20, [0, 5, 10, 15], False),  # 20 % of 20 levels, no run
        (20, [0, 5, 10, 15, 19], True),  # 25 % of 20 levels
    ],
)
def test_band_rule_runs_and_fraction(J, outside, refused):
    theo = np.ones(J)
    theo[outside] = 10.0
    b = band_check(unit_band(J), theo)
    assert b.refused is refused
    assert b.n_outside == len(outside) and b.n_levels == J
    tau = 2.0 ** (np.arange(1, J + 1)) / F
    if outside == [3, 4, 5]:
        assert b.ranges_s == [(tau[3], tau[5])] and b.longest_run == BAND_RUN
        assert b.text() == f"outside the 95 % WV band at τ = {tau[3]:.3g}–{tau[5]:.3g} s (3 of {J} scales)"
    assert band_check(unit_band(J), np.ones(J)).text() == f"inside the 95 % WV band at all {J} scales"


def test_a_narrow_band_is_widened_to_the_tolerance():
    J = 12
    narrow = unit_band(J)
    narrow = WaveletVariance(narrow.scales, narrow.variance, 0.99 * narrow.variance, 1.01 * narrow.variance,
                             narrow.n_coefficients, narrow.cov, F)
    assert band_check(narrow, np.full(J, 1.0 + 0.9 * BAND_TOLERANCE)).n_outside == 0
    assert band_check(narrow, np.full(J, 1.0 + 1.1 * BAND_TOLERANCE)).n_outside == J


def test_pair_check_compares_with_the_data():
    sigma = 0.02
    x = sigma * np.random.default_rng(5).standard_normal(2**14)
    wv = wavelet_variance(x, freq=F)
    n_true = sigma / math.sqrt(F)
    every = pair_check(wv, n_true, 0.0)  # the top levels rest on few coefficients: wide band, inside it
    assert every.n_outside == 0 and every.n_points == len(wv)
    assert every.tau_range_s == pytest.approx((1.0 / F, wv.scales[-1] / (2 * F)))
    good = pair_check(wv, n_true, 0.0, (0.01, 1.0))
    assert good.worst_ratio < 1.3 and good.n_outside == 0
    high = pair_check(wv, 2.0 * n_true, 0.0, (0.01, 1.0))  # AV ∝ N²: 4× above the data, outside its band
    assert high.above and high.worst_ratio == pytest.approx(4.0, rel=0.3)
    assert high.n_points == 7 and high.n_outside == 7 and high.outside_s == ((0.01, 0.64),)


@pytest.fixture(scope="module")
def ar1_wn():
    """AR1 (T_c = 1 s) + WN at 100 Hz: a WN fit leaves the band around the AR1's bump."""
    return as_model("AR1+WN").with_vector([0.99, 0.01, 1.0]).simulate(2**14, seed=3)


def test_richer_candidate_used_when_the_selected_one_leaves_the_band(ar1_wn):
    ranking = select_model(ar1_wn, freq=F, complete="AR1+WN", criterion="wvic")
    wn = ranking.by_structure("WN")
    assert band_check(wn.wv, wn.theoretical_wv).refused
    s = within_band(ranking, wn)
    assert str(s.fit.model) == "AR1 + WN" and not s.band.refused and s.selected == "WN"
    assert s.note.startswith("WN outside the 95 % WV band at τ = ") and s.note.endswith("stays inside: used")
    assert s.fit.extra["retry"]["selected"] == "WN"
    # the complete model reached: kept, and why
    only = within_band(select_model(ar1_wn, freq=F, complete="WN"))
    assert str(only.fit.model) == "WN" and only.band.refused
    assert only.note.endswith("no richer candidate in the selection (the complete model is reached)")


def test_export_refused_in_one_line_or_forced_with_the_warning_in_the_file(ar1_wn, tmp_path, capsys):
    csv = tmp_path / "gyro.csv"
    np.savetxt(csv, ar1_wn[:, None] * 1e-3, header="gyro_x", comments="", fmt="%.9g")
    base = ["fit", str(csv), "--column", "gyro_x", "--freq", "100", "--units", "rad/s", "--model", "WN",
            "--sensor", "gyro", "--export", "kalibr", "--export", "openvins", "--export", "json"]
    out = tmp_path / "refused"
    code = main([*base, "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2, err
    assert err[-1].startswith("imunoise fit: error: export refused: gyro_x (WN) exported pair vs data AV over T = ")
    assert "the data's own reading (what --force writes): N = " in err[-1]
    assert err[-1].endswith(f"(see {out / 'wv.png'}); --force writes the export with this warning in the file")
    assert not (out / "imu.yaml").exists() and not (out / "imu_noise.json").exists()

    out = tmp_path / "forced"
    assert main([*base, "--force", "--out", str(out)]) == 0
    warning = "gyro_x: the WN fit: exported pair vs data AV over T = "
    assert warning in capsys.readouterr().err
    assert "the data's Allan reading N = " in (out / "imu.yaml").read_text()  # what --force writes
    kalibr = (out / "imu.yaml").read_text().splitlines()
    assert kalibr[0].startswith(f"# WARNING (exported with --force): {warning}")
    ov = (out / "kalibr_imu_chain.yaml").read_text().splitlines()
    assert ov[0].startswith("%YAML:1.0") and ov[1].startswith(f"# WARNING (exported with --force): {warning}")
    assert read_export(out / "kalibr_imu_chain.yaml")["gyroscope_noise_density"] > 0  # still a valid file
    doc = json.loads((out / "imu_noise.json").read_text())
    assert doc["warnings"][0].startswith(warning) and doc["kind"] == "imunoise.export"


def test_with_warnings_leaves_a_clean_export_alone():
    assert with_warnings("%YAML:1.0\na: 1\n", "openvins", []) == "%YAML:1.0\na: 1\n"
    assert with_warnings('{"kind": "k", "a": 1}', "json", ["w"]) == json.dumps({"kind": "k", "warnings": ["w"], "a": 1},
                                                                               indent=1)


def test_export_command_applies_the_gate_to_a_saved_model(ar1_wn, tmp_path, capsys):
    """`imunoise export MODEL` checks the saved fit against its data as `fit --export` does: a fit that leaves
    its band is refused in one line, and `--force` writes the warning into the file."""
    csv = tmp_path / "gyro.csv"
    np.savetxt(csv, ar1_wn[:, None] * 1e-3, header="gyro_x", comments="", fmt="%.9g")
    assert main(["fit", str(csv), "--column", "gyro_x", "--freq", "100", "--units", "rad/s", "--model", "WN",
                 "--out", str(tmp_path / "fit")]) == 0  # fmt: skip
    capsys.readouterr()
    model = tmp_path / "fit" / "model.json"
    out = tmp_path / "imu.yaml"
    assert main(["export", str(model), "--to", "kalibr", "--sensor", "gyro", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("imunoise export: error: export refused: gyro_x (WN) exported pair vs data AV over T = ")
    assert not out.exists()
    assert main(["export", str(model), "--to", "kalibr", "--sensor", "gyro", "--force", "--out", str(out)]) == 0
    first = out.read_text().splitlines()[0]
    assert first.startswith("# WARNING (exported with --force): gyro_x: the WN fit: exported pair vs data AV over T = ")
    assert read_export(out)["gyroscope_noise_density"] > 0
