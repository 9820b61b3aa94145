"""`imunoise batch` interrupted: like every other command, its outputs appear in ``--out`` together when the run
completes, and Ctrl-C — in the parent or reaching the Dask worker processes with it — leaves ``--out`` as it was,
with one line and exit code 130 (real SIGINT sent at a named step, :func:`imunoise.io.interrupt.interrupt_point`)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from imunoise.cli import main
from imunoise.io.interrupt import TEST_ENV

REPO = Path(__file__).resolve().parents[2]


def logs(folder: Path, n_files: int = 3) -> str:
    folder.mkdir()
    for i in range(n_files):
        x = 1e-3 * np.random.default_rng(4200 + i).standard_normal(3000)
        np.savetxt(folder / f"log{i}.csv", x, header="gyro_x", comments="")
    return str(folder / "*.csv")


def snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def earlier_out(folder: Path) -> dict[str, bytes]:
    """An --out holding a user's file and the table and a model of an earlier batch."""
    folder.mkdir()
    (folder / "keep.txt").write_text("mine\n")
    (folder / "batch.csv").write_text("file,axis\nearlier,gyro_x\n")
    (folder / "log0.model.json").write_text('{"earlier": true}\n')
    return snapshot(folder)


def batch(glob: str, out: Path, *extra) -> list[str]:
    return ["batch", glob, "--freq", "100", "--model", "WN", *map(str, extra), "--out", str(out)]


def test_interrupted_sequential_batch_leaves_out_as_it_was(tmp_path, capsys, monkeypatch):
    out = tmp_path / "o"
    before = earlier_out(out)
    glob = logs(tmp_path / "logs")
    for point in ("batch-progress", "publish"):  # after the first file; everything staged, nothing published
        monkeypatch.setenv(TEST_ENV, point)
        assert main(batch(glob, out, "--scheduler", "sequential")) == 130
        assert capsys.readouterr().err.strip().splitlines()[-1] == "imunoise batch: interrupted (Ctrl-C)"
        assert snapshot(out) == before


def test_a_completed_batch_replaces_the_earlier_one_and_names_the_published_models(tmp_path, capsys):
    out = tmp_path / "o"
    earlier_out(out)
    (out / "gone.model.json").write_text('{"earlier": true}\n')  # a model of a file no longer in the fleet
    assert main(batch(logs(tmp_path / "logs", 2), out, "--scheduler", "sequential")) == 0
    capsys.readouterr()
    assert set(snapshot(out)) - {"batch.parquet"} == {"keep.txt", "batch.csv", "log0.model.json", "log1.model.json"}
    table = (out / "batch.csv").read_text()
    assert str(out / "log1.model.json") in table and ".partial" not in table


def test_ctrl_c_reaching_the_dask_workers_leaves_out_as_it_was(tmp_path):
    """The whole process group (the parent and its two Dask worker processes) gets a real SIGINT after the first
    file: one line, exit 130, no worker traceback, --out unchanged."""
    out = tmp_path / "o"
    before = earlier_out(out)
    r = subprocess.run([sys.executable, "-m", "imunoise", *batch(logs(tmp_path / "logs"), out, "--workers", 2)],
                       capture_output=True, text=True, timeout=600, start_new_session=True,
                       env={**os.environ, "PYTHONPATH": str(REPO / "src"), TEST_ENV: "batch-progress:group"})
    assert r.returncode == 130, r.stderr
    assert r.stderr.strip().splitlines()[-1] == "imunoise batch: interrupted (Ctrl-C)"
    assert "Traceback" not in r.stderr and "KeyboardInterrupt" not in r.stderr
    assert snapshot(out) == before
