"""Bad input, second round (issue 22): CSV shapes, degenerate data, model size, options and the Python
defaults a new user meets. Each case is read correctly, refused with one line naming the file or flag
(exit 2), or warned about with the warning kept in the output."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from conftest import one_line_error
from imunoise.cli import main
from imunoise.errors import DataError, ImunoiseError, ModelError
from imunoise.io.imu_input import read_imu_source
from imunoise.io.tabular import read_table

RNG = np.random.default_rng(22)
X = 1e-3 * RNG.standard_normal((3000, 3))  # a still gyro triad, rad/s, 100 Hz


def run_cli(argv: list, capsys) -> tuple[int, str, str]:
    try:
        code = main([str(a) for a in argv])
    except SystemExit as e:  # a flag refused while the arguments are parsed (argparse's own exit 2)
        code = e.code
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def write(path: Path, text: str, encoding: str = "utf-8") -> Path:
    path.write_text(text, encoding=encoding)
    return path


def gyro_csv(path: Path, header: str = "gyro_x,gyro_y", cols: int = 2, sep: str = ",") -> Path:
    rows = [sep.join(f"{v:.6e}" for v in r[:cols]) for r in X]
    return write(path, header + "\n" + "\n".join(rows) + "\n")


# ----------------------------------------------------------------------------------------------
# CSV shapes
# ----------------------------------------------------------------------------------------------
def test_semicolons_with_decimal_commas_are_read_as_numbers(tmp_path):
    rows = [f"{a:.6f};{b:.6f}".replace(".", ",") for a, b in X[:, :2]]
    p = write(tmp_path / "comma.csv", "gyro_x;gyro_y\n" + "\n".join(rows) + "\n")
    s = read_imu_source(p, freq=100.0)
    np.testing.assert_array_equal(s.data["gyro_x"], np.round(X[:, 0], 6))
    np.testing.assert_array_equal(s.data["gyro_y"], np.round(X[:, 1], 6))
    bare = read_table(write(tmp_path / "bare.csv", "1,5;2,3\n1,6;2,4\n1,4;2,2\n"))
    assert bare.data.tolist() == [[1.5, 2.3], [1.6, 2.4], [1.4, 2.2]]


def test_decimal_commas_in_a_comma_separated_file_are_refused(tmp_path, capsys):
    p = write(tmp_path / "one.csv", "\n".join(f"{v:.6f}".replace(".", ",") for v in X[:, 0]) + "\n")
    code, _, err = run_cli(["fit", p, "--freq", 100, "--model", "WN", "--out", tmp_path / "o"], capsys)
    one_line_error(code, err, "one.csv", "decimal comma", "decimal points")
    assert not (tmp_path / "o" / "model.json").exists()


def test_header_shorter_than_the_rows_is_refused(tmp_path, capsys):
    p = gyro_csv(tmp_path / "short.csv", header="gyro_x,gyro_y", cols=3)
    code, _, err = run_cli(["fit", p, "--freq", 100, "--model", "WN", "--columns", "gyro_x,gyro_y"], capsys)
    one_line_error(code, err, "short.csv", "names 2 columns", "rows have 3 fields", "1 column has no name")


@pytest.mark.parametrize("name", ["t", "time", "timestamp", "stamp", "header.stamp", "%time", "time_s", "Time"])
def test_a_column_named_like_time_is_the_time(tmp_path, name):
    p = tmp_path / "log.csv"
    t = np.arange(X.shape[0]) * 0.005
    write(p, f"{name},gyro_x\n" + "\n".join(f"{a:.4f},{b:.6e}" for a, b in zip(t, X[:, 0])) + "\n")
    s = read_imu_source(p)  # no --time-column, no --freq: the rate comes from the stamps
    assert s.axes == ["gyro_x"] and s.freq == pytest.approx(200.0, rel=1e-9)
    assert s.meta["time"] == {"time_column": name, "time_unit": "s", "time_column_found": True}
    assert "found by its name" in s.report.source


def test_batch_does_not_fit_the_stamp_column(tmp_path, capsys):
    p = tmp_path / "stamp.csv"
    t = np.arange(X.shape[0]) * 0.01
    write(p, "stamp,gyro_x\n" + "\n".join(f"{a:.4f},{b:.6e}" for a, b in zip(t, X[:, 0])) + "\n")
    out = tmp_path / "fleet"
    code, _, err = run_cli(["batch", p, "--model", "WN", "--scheduler", "sequential", "--out", out], capsys)
    assert code == 0, err
    rows = (out / "batch.csv").read_text().splitlines()
    assert len(rows) == 2 and rows[1].startswith(f"{p},gyro_x,ok,")
    assert ",100.0," in rows[1]  # the rate of the stamps


def test_one_column_mapped_to_two_axes_is_refused(tmp_path, capsys):
    p = gyro_csv(tmp_path / "g.csv", header="gx,gy")
    code, _, err = run_cli(
        ["fit", p, "--freq", 100, "--model", "WN", "--columns", "gyro_x=gx,gyro_y=gx", "--out", tmp_path / "o"], capsys
    )
    one_line_error(code, err, "--columns", "'gx'", "gyro_x", "gyro_y", "g.csv")
    assert not (tmp_path / "o" / "imu_model.json").exists()


def test_an_unknown_axis_name_is_refused_with_the_valid_ones(tmp_path, capsys):
    p = gyro_csv(tmp_path / "g.csv", header="gx,gy")
    code, _, err = run_cli(["fit", p, "--freq", 100, "--model", "WN", "--columns", "gyro_w=gx"], capsys)
    one_line_error(code, err, "--columns", "'gyro_w'", "gyro_x, gyro_y, gyro_z, accel_x, accel_y, accel_z")


def test_a_utf8_byte_order_mark_is_not_part_of_the_name(tmp_path, capsys):
    p = tmp_path / "excel.csv"
    write(p, "gyro_x\n" + "\n".join(f"{v:.6e}" for v in X[:, 0]) + "\n", encoding="utf-8-sig")
    assert p.read_bytes().startswith(b"\xef\xbb\xbf")
    s = read_imu_source(p, columns=["gyro_x"], freq=100.0)
    np.testing.assert_array_equal(s.data["gyro_x"], np.array([float(f"{v:.6e}") for v in X[:, 0]]))
    code, _, err = run_cli(["fit", p, "--freq", 100, "--column", "gyro_x", "--model", "WN", "--out", tmp_path / "o"],
                           capsys)
    assert code == 0, err
    assert json.loads((tmp_path / "o" / "model.json").read_text())["extra"]["column"] == "gyro_x"


def test_nanosecond_stamps_without_a_time_unit(tmp_path, capsys):
    p = tmp_path / "ns.csv"
    t = 1_700_000_000_000_000_000 + np.arange(X.shape[0], dtype=np.int64) * 5_000_000  # 200 Hz
    write(p, "t,gyro_x\n" + "\n".join(f"{a},{b:.6e}" for a, b in zip(t, X[:, 0])) + "\n")
    # the Python reader without a unit: ns from the spacing, said in a warning kept in the metadata
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        s = read_imu_source(p)
    assert s.freq == 200.0 and s.meta["time"]["time_unit"] == "ns"
    assert any("time unit taken as ns" in str(w.message) for w in caught)
    # the CLI, the column found by its name: the same reading, the warning kept in model.json
    out = tmp_path / "o"
    code, _, err = run_cli(["fit", p, "--column", "gyro_x", "--model", "WN", "--out", out], capsys)
    assert code == 0, err
    d = json.loads((out / "model.json").read_text())
    assert d["freq_hz"] == 200.0 and d["extra"]["timing"]["rate_hz"] == 200.0
    assert any("time unit taken as ns" in w for w in d["extra"]["warnings"])
    # --time-column t with --time-unit at its default s: refused with the flag and the unit that fits
    code, _, err = run_cli(["fit", p, "--time-column", "t", "--column", "gyro_x", "--model", "WN"], capsys)
    one_line_error(code, err, "ns.csv", "2e-07 Hz", "--time-unit ns")


# ----------------------------------------------------------------------------------------------
# data that cannot be modelled
# ----------------------------------------------------------------------------------------------
def test_zeros_with_one_spike_are_refused(tmp_path, capsys):
    z = np.zeros(5000)
    z[2500] = 1.0
    p = tmp_path / "spike.csv"
    np.savetxt(p, z, header="gyro_x", comments="")
    code, _, err = run_cli(["fit", p, "--freq", 100, "--model", "WN", "--out", tmp_path / "o"], capsys)
    one_line_error(code, err, "spike.csv", "'gyro_x'", "near-constant", "4999 of 5000 samples are exactly 0")
    assert not (tmp_path / "o" / "model.json").exists()
    np.savetxt(p, np.full(100, 0.0025), header="gyro_x", comments="")
    with pytest.raises(DataError, match=r"constant \(0.0025 in all 100 samples\)"):
        read_imu_source(p, freq=100.0)


def test_selection_needs_more_wavelet_levels_than_parameters(tmp_path, capsys):
    from imunoise.noise.selection import select_model

    ranking = select_model(X[:50, 0], freq=100.0, criterion="gof")  # 50 samples: J = 5 levels
    J = len(ranking.best.wv.variance)
    assert J == 5
    assert max(f.n_params for f in ranking.fits) == J - 1
    assert ranking.best.n_params < J
    reasons = dict(ranking.skipped)
    assert reasons["2*AR1 + RW"] == "5 parameters on 5 wavelet levels: needs at least 6 (more data)"
    p = tmp_path / "fifty.csv"
    np.savetxt(p, X[:50, 0], header="gyro_x", comments="")
    code, _, err = run_cli(["fit", p, "--freq", 100, "--auto", "--criterion", "gof", "--out", tmp_path / "o"], capsys)
    assert code == 0, err
    from imunoise.noise.model import Model

    assert Model.parse(json.loads((tmp_path / "o" / "model.json").read_text())["model"]).n_params < 5


def test_select_limit(tmp_path, capsys):
    p = tmp_path / "x.csv"
    np.savetxt(p, X[:1000, 0], header="gyro_x", comments="")
    code, _, err = run_cli(["select", p, "--freq", 100, "--limit", -1, "--out", tmp_path / "bad"], capsys)
    one_line_error(code, err, "--limit", "got -1")
    code, out, err = run_cli(["select", p, "--freq", 100, "--limit", 5, "--out", tmp_path / "o"], capsys)
    assert code == 0, err
    n_fitted = sum(1 for r in (tmp_path / "o" / "ranking.csv").read_text().splitlines()[1:] if r[0].isdigit())
    assert f"... {n_fitted - 5} more" in out
    code, out, err = run_cli(["select", p, "--freq", 100, "--limit", 0, "--out", tmp_path / "o"], capsys)
    assert code == 0 and "more (ranking.table() shows all)" not in out
    assert sum(1 for ln in out.splitlines() if ln[:4].strip().isdigit()) == n_fitted


# ----------------------------------------------------------------------------------------------
# files and options
# ----------------------------------------------------------------------------------------------
def test_gmwmfit_load_of_a_yaml_names_the_file(tmp_path):
    from imunoise.noise.fitting.result import GMWMFit

    p = write(tmp_path / "model.yaml", "kind: imunoise.fit\nmodel: WN\nparams: {WN.sigma2: 1.0e-6}\n")
    with pytest.raises(ImunoiseError, match="model.yaml is not JSON") as exc:
        GMWMFit.load(str(p))
    assert "GMWMFit.save" in str(exc.value)
    q = write(tmp_path / "other.json", json.dumps({"kind": "something else"}))
    with pytest.raises(ModelError, match="other.json.*not an imunoise fit JSON"):
        GMWMFit.load(str(q))


def test_workers_zero_is_refused(tmp_path, capsys):
    from imunoise.batch import run_batch

    p = gyro_csv(tmp_path / "g.csv")
    code, _, err = run_cli(["batch", p, "--freq", 100, "--model", "WN", "--workers", 0, "--out", tmp_path / "o"],
                           capsys)
    one_line_error(code, err, "--workers", "got 0")
    with pytest.raises(ModelError, match="n_workers"):
        run_batch([str(p)], {"freq": 100.0, "model": "WN"}, tmp_path / "o", n_workers=0)


# ----------------------------------------------------------------------------------------------
# the Python API's defaults are the CLI's
# ----------------------------------------------------------------------------------------------
def test_select_model_defaults_to_wvic_and_needs_the_rate():
    from imunoise.noise.selection import select_model
    from imunoise.noise.wv import wavelet_variance

    x = np.random.default_rng(5).standard_normal(40_000)
    ranking = select_model(x, freq=100.0)
    assert ranking.criterion == "wvic" and str(ranking.best.model) == "WN"
    with pytest.raises(DataError, match="freq=HZ"):
        select_model(x)
    wv = wavelet_variance(x, freq=200.0)
    assert select_model(wv, complete="WN+RW").best.freq == 200.0  # the WV carries its rate
    with pytest.raises(DataError, match="200 Hz"):
        select_model(wv, freq=100.0, complete="WN+RW")


@pytest.mark.parametrize("flag, value", [("--max-iter", 0), ("--max-iter", -1), ("--tol", -1), ("--tol", "nan")])
def test_em_iteration_options_are_checked(tmp_path, capsys, flag, value):
    p = gyro_csv(tmp_path / "g.csv", header="gyro_x", cols=1)
    code, _, err = run_cli(["em", p, "--freq", 100, "--model", "WN", flag, value, "--out", tmp_path / "o"], capsys)
    one_line_error(code, err, flag, "got", str(value))
    assert not (tmp_path / "o").exists()


def test_the_stamp_unit_rule():
    from imunoise.io.time_column import infer_time_unit

    assert infer_time_unit(0.005, None, "f") == ("s", None)
    assert infer_time_unit(20.0, None, "f")[0] == "ms"  # 50 Hz
    assert infer_time_unit(500.0, None, "f")[0] == "us"  # 2 kHz (2 Hz in ms is not a typical IMU rate)
    assert infer_time_unit(5e6, None, "f")[0] == "ns"
    assert infer_time_unit(5e6, "ns", "f") == ("ns", None)
    with pytest.raises(DataError, match="10 Hz in ms or 1e\\+04 Hz in us; give --time-unit"):
        infer_time_unit(100.0, None, "f")  # on the boundary of two units: asked, not guessed
    with pytest.raises(DataError, match="give --time-unit ms"):
        infer_time_unit(10.0, "s", "f")  # 0.1 Hz in s, 100 Hz in ms
