"""`imunoise fit --stream`: the one-pass wavelet variance of a file read block by block equals the whole-file
path's (1e-9 relative), and so does the fit (issue "Calibrate from the logs people already have" §3)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from imunoise.cli import main
from imunoise.io.imu_input import read_imu_source
from imunoise.io.imu_stream import StreamOrderError, open_imu_blocks
from imunoise.io.rosbag import write_imu_bag
from imunoise.noise.wv import wavelet_variance
from imunoise.noise.wv_log import stream_wavelet_variance

N = 6000
F = 100.0


def _gyro(seed: int, n: int = N) -> np.ndarray:
    """White noise + AR1 + a random walk, rad/s (a static gyro)."""
    rng = np.random.default_rng(seed)
    ar = np.zeros(n)
    e = 3e-5 * rng.standard_normal(n)
    for i in range(1, n):
        ar[i] = 0.99 * ar[i - 1] + e[i]
    return 1e-3 * rng.standard_normal(n) + ar + np.cumsum(2e-6 * rng.standard_normal(n)) + 2e-4


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("stream")
    x = np.column_stack([_gyro(s) for s in range(3)])
    t = 1.7e9 + np.arange(N) / F
    np.savetxt(
        d / "g.csv", np.column_stack([t, np.degrees(x)]), header="t,gx,gy,gz", comments="", delimiter=",", fmt="%.17g"
    )
    np.save(d / "g.npy", np.degrees(x))
    np.savez(d / "g.npz", data=np.degrees(x), columns=np.array(["gx", "gy", "gz"]), units="deg/s", freq_hz=F)
    acc = np.column_stack([_gyro(s + 3) * 10 for s in range(2)] + [9.81 + _gyro(5) * 10])
    bag = write_imu_bag(d / "imu.bag", t, x, acc)
    return {"dir": d, "csv": d / "g.csv", "npy": d / "g.npy", "npz": d / "g.npz", "bag": bag}


def _both(path, chunk_rows=997, **kw):
    """(whole-file series, streamed WVs) of the same input, read in blocks of ``chunk_rows``."""
    dec = {k: kw.pop(k) for k in ("decimate_by",) if k in kw}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        series = read_imu_source(path, **kw, **dec)
        blocks = open_imu_blocks(path, chunk_rows=chunk_rows, **kw)
        streamed = stream_wavelet_variance(blocks, freq=kw.get("freq"), **dec)
    return series, streamed


def _assert_same_wv(series, streamed):
    assert streamed.axes == series.axes
    assert streamed.freq == series.freq
    for axis in series.axes:
        ref = wavelet_variance(series.data[axis], freq=series.freq)
        got = streamed.wv[axis]
        np.testing.assert_array_equal(got.scales, ref.scales)
        np.testing.assert_array_equal(got.n_coefficients, ref.n_coefficients)
        for name in ("variance", "ci_low", "ci_high", "cov"):
            np.testing.assert_allclose(getattr(got, name), getattr(ref, name), rtol=1e-9, atol=0, err_msg=name)
        assert got.freq == ref.freq


@pytest.mark.parametrize(
    "kind, kw",
    [
        ("csv", {"columns": {"gyro_x": "gx", "gyro_z": "gz"}, "units": "deg/s", "time_column": "t"}),
        ("csv", {"columns": ["gy"], "units": "deg", "freq": F}),  # increments: rate = increment·f
        ("csv", {"columns": ["gy"], "units": "deg", "time_column": "t", "decimate_by": 3}),  # f from the stamps
        ("npy", {"columns": ["0", "2"], "units": "deg/s", "freq": F, "decimate_by": 4}),
        ("npz", {}),  # units and rate from the file
        ("bag", {}),
        ("bag", {"columns": "gyro_y,accel_z", "decimate_by": 2}),
    ],
)
def test_streamed_wv_equals_the_whole_file(files, kind, kw):
    series, streamed = _both(files[kind], **kw)
    _assert_same_wv(series, streamed)
    assert streamed.unit == series.unit and streamed.source_unit == series.source_unit
    if series.report is not None:
        assert streamed.report.to_dict() == series.report.to_dict()
    assert streamed.n_samples == len(series)


def test_unit_check_and_duplicates_as_in_the_whole_file(tmp_path):
    x = np.degrees(_gyro(7, 3000))  # deg/s without --units: the whole-file path warns
    t = np.arange(x.size) / F
    t[1000] = t[999]  # one duplicated stamp: dropped, the first kept
    path = tmp_path / "dup.csv"
    np.savetxt(path, np.column_stack([t, x]), header="t,gyro_x", comments="", delimiter=",", fmt="%.17g")
    with warnings.catch_warnings(record=True) as whole:
        warnings.simplefilter("always")
        series = read_imu_source(path, time_column="t")
    with warnings.catch_warnings(record=True) as one_pass:
        warnings.simplefilter("always")
        streamed = stream_wavelet_variance(open_imu_blocks(path, time_column="t", chunk_rows=500))
    assert sorted(str(w.message) for w in one_pass) == sorted(str(w.message) for w in whole)
    assert any("--units deg/s" in str(w.message) for w in one_pass)
    assert streamed.report.n_duplicates == 1 and streamed.n_samples == x.size - 1
    _assert_same_wv(series, streamed)


def test_out_of_order_stamps_are_refused_when_forced_and_read_whole_otherwise(tmp_path, capsys):
    x = np.degrees(_gyro(8, 3000))
    t = np.arange(x.size) / F
    t[[2000, 2001]] = t[[2001, 2000]]
    path = tmp_path / "swap.csv"
    np.savetxt(path, np.column_stack([t, x]), header="t,gyro_x", comments="", delimiter=",", fmt="%.17g")
    with pytest.raises(StreamOrderError, match="go back"):
        stream_wavelet_variance(open_imu_blocks(path, time_column="t", units="deg/s"))
    args = ["fit", path, "--time-column", "t", "--units", "deg/s", "--model", "WN", "--out", tmp_path / "o"]
    assert main([str(a) for a in [*args, "--stream"]]) == 2
    assert "go back" in capsys.readouterr().err
    # over the threshold but not forced: one line, then the whole-file path (which sorts)
    assert main([str(a) for a in [*args, "--stream-above", "100"]]) == 0
    err = capsys.readouterr().err
    assert "streaming" in err and "reading the whole file instead" in err


def _fit_json(argv, out):
    assert main([str(a) for a in [*argv, "--out", out]]) == 0
    name = "model.json" if (out / "model.json").exists() else "imu_model.json"
    return json.loads((out / name).read_text())


def _params(doc):
    if "axes" in doc:
        return {f"{a}.{k}": v for a, d in doc["axes"].items() for k, v in d["params"].items()}
    return doc["params"]


@pytest.mark.parametrize(
    "kind, argv",
    [
        ("csv", ["--column", "gx", "--time-column", "t", "--units", "deg/s", "--model", "AR1+WN+RW"]),
        ("npy", ["--columns", "gyro_x=0,gyro_y=1", "--freq", F, "--model", "WN+RW"]),  # deg/s, no unit: a warning
        ("bag", ["--model", "WN+RW", "--max-scale", 10]),
    ],
)
def test_fit_stream_gives_the_whole_file_fit(files, kind, argv, tmp_path, capsys):
    whole = _fit_json(["fit", files[kind], *argv], tmp_path / "whole")
    streamed = _fit_json(["fit", files[kind], *argv, "--stream"], tmp_path / "stream")
    capsys.readouterr()
    a, b = _params(whole), _params(streamed)
    fits = list(streamed["axes"].values()) if "axes" in streamed else [streamed]
    assert all("streamed" in f["extra"] and "data_allan" not in f["extra"] for f in fits)
    assert all(f["data_span"] == g["data_span"] for f, g in zip(fits, whole.get("axes", {"": whole}).values()))
    assert whole.get("extra", {}).get("warnings") == streamed.get("extra", {}).get("warnings")
    assert a.keys() == b.keys()
    for k in a:
        assert b[k] == pytest.approx(a[k], rel=1e-6), k


def test_stream_refuses_robust_in_one_line(files, tmp_path, capsys):
    code = main(
        [
            str(a)
            for a in [
                "fit",
                files["npy"],
                "--column",
                "0",
                "--freq",
                F,
                "--model",
                "WN",
                "--robust",
                "--stream",
                "--out",
                tmp_path / "o",
            ]
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and "--robust" in err and len(err.strip().splitlines()) == 1
