"""`imunoise batch`: Dask local cluster vs the plain loop, broken files reported, per-file model JSON."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from imunoise.batch import _names, expand_paths, process_file, run_batch, run_sequential
from imunoise.cli import main
from imunoise.errors import DataError
from imunoise.noise.imu_model import ImuModel
from imunoise.noise.model import Model

CFG = {"freq": 100.0, "model": "WN+RW", "units": {"gyro": "deg/s", "accel": "g"}}


def _logs(folder, n_files=4, n=4096):
    folder.mkdir()
    m = Model.parse("WN+RW").with_params({"WN.sigma2": 1e-2, "RW.gamma2": 1e-8})
    for i in range(n_files):
        x = np.column_stack([m.simulate(n, seed=2 * i), m.simulate(n, seed=2 * i + 1)])
        np.savetxt(folder / f"log{i:02d}.csv", x, delimiter=",", header="gyro_z,accel_z", comments="")
    (folder / "log99.csv").write_text("gyro_z,accel_z\n1,2\n3,oops\n")  # broken
    return sorted(str(p) for p in folder.glob("*.csv"))


def test_dask_local_matches_sequential_and_reports_broken_file(tmp_path):
    paths = _logs(tmp_path / "logs")
    par = run_batch(paths, CFG, tmp_path / "dask", n_workers=2, progress=False)
    seq = run_sequential(paths, CFG, tmp_path / "seq")
    assert par.failed == seq.failed == [paths[-1]]
    assert par.n_files == 5 and len(par.rows) == 4 * 2 + 1
    bad = [r for r in par.rows if r["status"] == "error"][0]
    assert "oops" in bad["error"] and bad["file"] == paths[-1]
    keys = ("file", "axis", "model", "noise_density", "random_walk_eq", "objective")
    assert [tuple(r[k] for k in keys) for r in par.rows] == [tuple(r[k] for k in keys) for r in seq.rows]
    with open(par.tables[0]) as fh:
        table = list(csv.DictReader(fh))
    assert len(table) == 9 and table[0]["noise_density_unit"] == "rad/s/sqrt(Hz)"
    assert table[1]["random_walk_unit"] == "m/s^3/sqrt(Hz)"
    model = ImuModel.load(tmp_path / "dask" / "log00.model.json")
    assert list(model.axes) == ["gyro_z", "accel_z"] and model.axes["gyro_z"]["unit"] == "rad/s"
    assert float(table[0]["noise_density"]) == pytest.approx(
        model.axes["gyro_z"]["continuous"]["WN.noise_density"], rel=1e-12
    )


def test_process_file_never_raises_and_names_are_unique(tmp_path):
    rows = process_file(str(tmp_path / "missing.csv"), CFG, str(tmp_path), "missing")
    assert rows[0]["status"] == "error" and "not found" in rows[0]["error"]
    assert _names(["a/x.csv", "b/x.csv", "c/y.csv"])[2] == "y"
    assert len(set(_names(["a/x.csv", "b/x.csv"]))) == 2
    with pytest.raises(DataError, match="no files match"):
        expand_paths(str(tmp_path / "*.nothing"))
    t = np.arange(2000) * 0.01
    t[500] = t[499]  # one duplicated stamp: dropped, counted and noted in the table
    x = np.random.default_rng(0).normal(size=2000)
    np.savetxt(tmp_path / "dup.csv", np.column_stack([t, x]), delimiter=",", header="t,gyro_z", comments="")
    cfg = {"model": "WN", "time_column": "t", "units": "rad/s"}
    (row,) = process_file(str(tmp_path / "dup.csv"), cfg, str(tmp_path), "dup")
    assert row["status"] == "ok" and row["n_samples"] == 1999 and "dropped 1 samples" in row["notes"]
    assert row["freq_hz"] == pytest.approx(100.0, rel=1e-3)


def test_cli_batch_sequential(tmp_path, capsys):
    paths = _logs(tmp_path / "logs", n_files=2, n=2048)
    out = tmp_path / "out"
    code = main(["batch", str(tmp_path / "logs" / "*.csv"), "--freq", "100", "--model", "WN", "--units",
                 "gyro=deg/s,accel=g", "--scheduler", "sequential", "--out", str(out)])  # fmt: skip
    assert code == 1  # one file failed
    text = capsys.readouterr().out
    assert "modelled 2/3 files" in text and f"FAILED {paths[-1]}" in text
    d = json.loads((out / "log01.model.json").read_text())
    assert d["kind"] == "imunoise.noise.imu_model" and d["axes"]["accel_z"]["unit"] == "m/s²"
