"""The third bad-input round: interrupted runs of every command, replayed recordings in the wrong units, law
files out of range.

Ctrl-C is sent deterministically: ``IMUNOISE_TEST_SIGINT=POINT`` makes the run send itself a real SIGINT at a
named step (:func:`imunoise.io.interrupt.interrupt_point`): ``publish`` (every output staged, none published
yet), the name of a file just written, or ``experiment-progress`` (a Monte Carlo job done, the others running
in worker processes). The run must end with one line and exit code 130 and leave ``--out`` exactly as it was.
"""

from __future__ import annotations

import gzip
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from imunoise.cli import main
from imunoise.io.interrupt import TEST_ENV
from imunoise.sim.drive import DriveConfig, simulate_drive

REPO = Path(__file__).resolve().parents[2]
DRIVE = REPO / "data" / "drive_0708"


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict[str, Path]:
    """A static gyro table (rad/s, 100 Hz) and 45 s of drive_0708 (34.5 s still, then driving)."""
    d = tmp_path_factory.mktemp("in")
    x = 1e-3 * np.random.default_rng(0).standard_normal(3000)
    np.savetxt(d / "ok.csv", x, header="gyro_x", comments="")
    with gzip.open(DRIVE / "imu_body_inc.txt.gz", "rt") as fh:
        (d / "imu.txt").write_text("".join(next(fh) for _ in range(4500)))
    (d / "gnss.txt").write_text("".join((DRIVE / "gnss_rtk.txt").read_text().splitlines(keepends=True)[:400]))
    cfg = DriveConfig(duration_s=200.0, n_stops=1, stop_range_s=(25.0, 30.0), static_s=40.0, outages=[(100.0, 15.0)],
                      seed=3900)
    simulate_drive(cfg, "mems", seed=3900).write(d / "sim")  # stops enough to calibrate from
    return {p.name: p for p in d.iterdir()}


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (hidden ones too) with its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def earlier_out(folder: Path) -> dict[str, bytes]:
    """An --out that already holds a user's file and the outputs of an earlier run."""
    folder.mkdir()
    (folder / "keep.txt").write_text("mine\n")
    (folder / "model.json").write_text('{"earlier": true}\n')
    (folder / "metrics.json").write_text('{"earlier": true}\n')
    return snapshot(folder)


def commands(i: dict[str, Path]) -> dict[str, list]:
    nav_in = ["--imu", i["imu.txt"], "--gnss", i["gnss.txt"]]
    return {
        "fit": ["fit", i["ok.csv"], "--freq", 100, "--model", "WN"],
        "select": ["select", i["ok.csv"], "--freq", 100],
        "allan": ["allan", i["ok.csv"], "--freq", 100],
        "em": ["em", i["ok.csv"], "--freq", 100, "--model", "WN", "--max-iter", 3],
        "compare": ["compare", i["ok.csv"], "--freq", 100, "--em-max-iter", 3],
        "detect": ["detect", "--imu", i["imu.txt"]],
        "calibrate": ["calibrate", i["sim"]],
        "nav": ["nav", *nav_in, "--no-plots"],
        "online": ["online", *nav_in],
        "simulate": ["simulate", "--duration", 160, "--stops", 1, "--static-start", 30],
        "demo": ["demo", "--static", "--duration", 120],
    }


@pytest.mark.parametrize(
    ("cmd", "point"),
    [("fit", "publish"), ("fit", "wv.png"), ("select", "publish"), ("allan", "publish"), ("em", "publish"),
     ("compare", "publish"), ("detect", "summary.json"), ("calibrate", "calibration.json"), ("nav", "publish"),
     ("online", "publish"), ("simulate", "publish"), ("demo", "publish")],
)
def test_interrupted_command_leaves_out_as_it_was(cmd, point, inputs, tmp_path, capsys, monkeypatch):
    out = tmp_path / "o"
    before = earlier_out(out)
    monkeypatch.setenv(TEST_ENV, point)
    code = main([str(a) for a in [*commands(inputs)[cmd], "--out", out]])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 130
    assert err[-1] == f"imunoise {cmd}: interrupted (Ctrl-C)"
    assert snapshot(out) == before  # nothing added, replaced or removed; no staging folder left


def test_interrupted_calibrate_keeps_the_earlier_calibration_whole(inputs, tmp_path, capsys, monkeypatch):
    """The reported case: a model without calibration.json / report. A complete earlier calibration in --out
    stays complete and unchanged when the next one is interrupted between its model and its calibration.json."""
    out = tmp_path / "c"
    argv = [str(a) for a in [*commands(inputs)["calibrate"], "--out", out]]
    assert main(argv) == 0
    first = snapshot(out)
    assert {"imu_model.json", "calibration.json", "report.html"} <= set(first)
    monkeypatch.setenv(TEST_ENV, "calibration.json")
    assert main(argv) == 130
    assert snapshot(out) == first
    capsys.readouterr()


def run_module(argv: list, env: dict[str, str], **kw) -> subprocess.CompletedProcess:
    """`python -m imunoise ...` as a user runs it (the command-line path: SIGINT remembered, workers forked)."""
    return subprocess.run([sys.executable, "-m", "imunoise", *map(str, argv)], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(REPO / "src"), **env}, timeout=900, **kw)


def test_a_swallowed_interrupt_still_ends_with_130_and_publishes_nothing(inputs, tmp_path):
    """The llvmlite case: the KeyboardInterrupt is raised and swallowed inside a callback, the run goes on; it
    must not finish with exit 0 and publish its outputs."""
    out = tmp_path / "o"
    before = earlier_out(out)
    r = run_module([*commands(inputs)["fit"], "--out", out], {TEST_ENV: "wv.png:swallowed"})
    assert r.returncode == 130, r.stderr
    assert r.stderr.strip().splitlines()[-1] == "imunoise fit: interrupted (Ctrl-C)"
    assert "Traceback" not in r.stderr
    assert snapshot(out) == before


@pytest.mark.slow
def test_interrupted_monte_carlo_with_workers(tmp_path):
    """Ctrl-C reaches the whole process group (the parent and its two workers) after the first job: one line,
    exit 130, no worker traceback, --out unchanged."""
    out = tmp_path / "mc"
    before = earlier_out(out)
    r = run_module(["experiment", "online", "--sim", "--seeds", 3, "--workers", 2, "--duration", 260, "--stops", 1,
                    "--outages", 1, "--methods", "plain", "--out", out],
                   {TEST_ENV: "experiment-progress:group"}, start_new_session=True)
    assert r.returncode == 130, r.stderr
    assert r.stderr.strip().splitlines()[-1] == "imunoise experiment: interrupted (Ctrl-C)"
    assert "Traceback" not in r.stderr and "KeyboardInterrupt" not in r.stderr
    assert snapshot(out) == before


def test_a_reused_fit_out_keeps_no_file_of_the_earlier_fit(tmp_path, capsys):
    """Second round, still open: a three-axis fit, then a one-axis fit into the same --out; the per-axis plots
    and imu_model.json of the first must not be read as part of the second."""
    rng = np.random.default_rng(3)
    three = tmp_path / "three.csv"
    np.savetxt(three, 1e-3 * rng.standard_normal((3000, 3)), delimiter=",", header="gyro_x,gyro_y,gyro_z",
               comments="")
    out = tmp_path / "fit"
    out.mkdir()
    (out / "notes.txt").write_text("mine\n")
    columns = ["--columns", "gyro_x,gyro_y,gyro_z"]
    assert main(["fit", str(three), "--freq", "100", "--model", "WN", *columns, "--out", str(out)]) == 0
    assert {"imu_model.json", "wv_gyro_x.png", "wv_gyro_z.png"} <= set(snapshot(out))
    assert main(["fit", str(three), "--freq", "100", "--model", "WN", "--column", "gyro_y", "--out", str(out)]) == 0
    assert set(snapshot(out)) == {"model.json", "wv.png", "notes.txt"}
    capsys.readouterr()


# ----------------------------------------------------------------------------------------------
# replayed recordings (--imu-noise) and motion-law files
# ----------------------------------------------------------------------------------------------
COLS = np.array(["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"])


def recording(path: Path, units: list[str], scale=(1.0,) * 6, **keys) -> str:
    """A static recording like the shared ADIS16405 logs (deg/s and g), its columns multiplied by ``scale``."""
    rng = np.random.default_rng(3901)
    data = rng.normal(0.0, 1.0, (20_000, 6)) * [0.35, 0.37, 0.43, 0.004, 0.003, 0.004] + [0.4, -0.4, -0.3, 0.0,
                                                                                          0.0, -1.0]
    np.savez(path, **{"data": data * np.asarray(scale), "columns": COLS, "units": np.array(units),
                      "freq_hz": np.float64(100.0), **keys})
    return str(path)


def test_the_adis_like_recording_is_read(tmp_path):
    from imunoise.sim.replay import load_recording

    rec = load_recording(recording(tmp_path / "ok.npz", ["deg/s"] * 3 + ["g"] * 3))
    assert rec.errors.std(axis=0)[0] == pytest.approx(np.radians(0.35), rel=0.03)


@pytest.mark.parametrize(
    ("units", "scale", "says"),
    [(["rad/s"] * 3 + ["g"] * 3, (1.0,) * 6, "look like deg/s"),  # deg/s labelled rad/s: 57× the noise
     (["deg/s"] * 3 + ["m/s^2"] * 3, (1.0,) * 6, "look like g"),  # g labelled m/s²: 9.8× too little
     (["deg/s"] * 3 + ["g"] * 3, (1.0,) * 3 + (9.80665,) * 3, "look like m/s² labelled g")],
)
def test_recording_in_other_units_than_stated_is_refused(units, scale, says, tmp_path):
    from imunoise.errors import DataError
    from imunoise.sim.replay import load_recording

    path = recording(tmp_path / "rec.npz", units, scale)
    with pytest.raises(DataError, match=says) as e:
        load_recording(path)
    assert str(e.value).startswith(f"--imu-noise {path}: key 'units'") and "\n" not in str(e.value)


def test_recording_in_the_wrong_unit_is_one_line_on_the_command_line(tmp_path, capsys):
    path = recording(tmp_path / "degs.npz", ["rad/s"] * 3 + ["g"] * 3)
    code = main(["experiment", "online", "--sim", "--imu-noise", path, "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "look like deg/s" in err[0] and path in err[0]


def test_malformed_recordings_are_one_line(tmp_path):
    from imunoise.errors import DataError
    from imunoise.sim.replay import load_recording

    units = ["deg/s"] * 3 + ["g"] * 3
    cases = {
        "freq_array": (recording(tmp_path / "fa.npz", units, freq_hz=np.array([100.0, 100.0])), "key 'freq_hz'"),
        "pickled": (recording(tmp_path / "pk.npz", units, columns=np.array(list(COLS), dtype=object)),
                    "key 'columns' is a pickled"),
    }
    full = Path(recording(tmp_path / "full.npz", units)).read_bytes()
    (tmp_path / "trunc.npz").write_bytes(full[: len(full) // 2])
    cases["truncated"] = (str(tmp_path / "trunc.npz"), "cannot read it as .npz")
    (tmp_path / "cut.npz").write_bytes(full[:-200])  # the archive's index cut
    cases["cut"] = (str(tmp_path / "cut.npz"), "cannot read it as .npz")
    for name, (path, says) in cases.items():
        with pytest.raises(DataError) as e:
            load_recording(path)
        msg = str(e.value)
        assert msg.startswith(f"--imu-noise {path}: ") and says in msg and "\n" not in msg, (name, msg)


def test_law_values_beyond_plausible_ranges_are_refused():
    from imunoise.errors import ModelError
    from imunoise.sim.law_files import law_from_dict

    with pytest.raises(ModelError, match=r"key 'white.speed' has 1e\+06 for gyro_x, outside the plausible range"):
        law_from_dict({"white": {"speed": [1e6] * 6}}, "motion law x.json")
    with pytest.raises(ModelError, match="key .moving_gm.sigma. has 10 m/s²"):
        law_from_dict({"moving_gm": {"sigma": [0, 0, 0, 0.1, 0.1, 10.0], "tau_s": [100.0] * 6}}, "law")
    with pytest.raises(ModelError, match="key 'departure_step' has 0.5 rad/s"):
        law_from_dict({"departure_step": [0.5, 0, 0, 0, 0, 0]}, "law")
    ok = law_from_dict({"white": {"speed": [6.0] * 6}, "moving_gm": {"sigma": [1e-3] * 3 + [0.05] * 3,
                                                                      "tau_s": [60.0] * 6}}, "law")
    assert ok.white_speed == (6.0,) * 6 and ok.moving_gm_sigma[3] == 0.05


def test_a_term_with_its_time_constant_but_no_size_is_refused(tmp_path, capsys):
    """`moving_gm` with tau_s and no sigma was silently a law without the term."""
    import json

    law = tmp_path / "gm.json"
    law.write_text(json.dumps({"moving_gm": {"tau_s": [60.0] * 6}}))
    code = main(["experiment", "online", "--sim", "--motion-noise", str(law), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert str(law) in err[0] and "key 'moving_gm.sigma' is needed with 'moving_gm.tau_s'" in err[0]
    from imunoise.errors import ModelError
    from imunoise.sim.law_files import law_from_dict

    with pytest.raises(ModelError, match="key 'warmup.amplitude' is needed with 'warmup.tau_s'"):
        law_from_dict({"warmup": {"tau_s": 100.0}}, "law")


# ----------------------------------------------------------------------------------------------
# second round, still open: transposed arrays and huge sparse inputs
# ----------------------------------------------------------------------------------------------
def test_a_transposed_npy_is_named_as_such(tmp_path, capsys):
    x = 1e-3 * np.random.default_rng(3902).standard_normal((20_000, 6))
    np.save(tmp_path / "t.npy", x.T)
    code = main(["fit", str(tmp_path / "t.npy"), "--freq", "100", "--model", "WN", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "t.npy: the array has shape (6, 20000)" in err[0] and "save it transposed" in err[0]
    assert "constant" not in err[0] and "samples; need" not in err[0]


@pytest.mark.parametrize("what", ["fit", "nav"])
def test_a_sparse_gigabyte_is_refused_from_its_head(what, tmp_path, capsys, monkeypatch):
    """1 GiB of NULs (a sparse file: no disk used): refused in one line after reading its first bytes, not the
    whole gigabyte (the reader is handed at most the sniffed head: counted here)."""
    import builtins

    big = tmp_path / "big.txt"
    with open(big, "wb") as fh:
        fh.truncate(1 << 30)
    largest = [0]
    real_open = builtins.open

    class Counting:
        def __init__(self, fh):
            self.fh = fh

        def read(self, n=-1):
            data = self.fh.read(n)
            largest[0] = max(largest[0], len(data))
            return data

        def __getattr__(self, name):
            return getattr(self.fh, name)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.fh.close()

    def counting_open(file, mode="r", *a, **k):
        fh = real_open(file, mode, *a, **k)
        return Counting(fh) if str(file) == str(big) and "b" in mode else fh

    monkeypatch.setattr(builtins, "open", counting_open)
    argv = (["fit", str(big), "--freq", "100", "--model", "WN"] if what == "fit"
            else ["nav", "--imu", str(big), "--gnss", str(DRIVE / "gnss_rtk.txt")])
    code = main([*argv, "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "big.txt is not a text file" in err[0]
    assert 0 < largest[0] <= 1 << 20  # read through open(), never the gigabyte


# ----------------------------------------------------------------------------------------------
# numba's kernel cache: a NUMBA_CACHE_DIR that cannot be written, no writable cache at all
# ----------------------------------------------------------------------------------------------
def test_warm_up_refuses_a_cache_dir_it_cannot_write(tmp_path, capsys, monkeypatch):
    """numba would silently cache elsewhere and the warm-up report success: one line before any work."""
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(blocker / "cache"))  # under a file: cannot be created
    code = main(["warm-up"])
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert code == 2 and len(err) == 1 and captured.out == ""  # nothing run
    assert err[0].startswith(f"imunoise warm-up: error: NUMBA_CACHE_DIR={blocker / 'cache'}: cannot write")
    assert "point NUMBA_CACHE_DIR to a writable folder" in err[0]


NO_LOCATOR = """
import sys
import numba.core.caching as caching
caching.CacheImpl._locator_classes = []  # as on a read-only install without a writable home
from imunoise.cli import main
sys.argv = ["imunoise", *sys.argv[1:]]
sys.exit(main())
"""


def test_no_writable_kernel_cache_is_one_line(inputs, tmp_path):
    r = subprocess.run([sys.executable, "-c", NO_LOCATOR, "allan", str(inputs["ok.csv"]), "--freq", "100", "--out",
                        str(tmp_path / "o")], capture_output=True, text=True, timeout=300,
                       env={**os.environ, "PYTHONPATH": str(REPO / "src")})
    err = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(err) == 1, r.stderr
    assert "no writable place for its kernel cache" in err[0] and "set NUMBA_CACHE_DIR" in err[0]


@pytest.mark.parametrize("header", ["sow;gx;gy;gz;ax;ay;az", "sow,gx,gy,gz,ax,ay,az"])
def test_decimal_commas_in_an_imu_file_are_named(header, tmp_path):
    """Second round, still open: a spreadsheet export (1,25;3,5) was 'non-numeric' or blamed on the header."""
    from imunoise.errors import DataError
    from imunoise.io.kfgins import read_imu

    x = 1e-3 * np.random.default_rng(3904).standard_normal((50, 6))
    rows = [";".join([f"{i * 0.01:.2f}", *(f"{v:.6e}" for v in r)]).replace(".", ",") for i, r in enumerate(x)]
    path = tmp_path / "comma.csv"
    path.write_text(header + "\n" + "\n".join(rows) + "\n")
    with pytest.raises(DataError) as e:
        read_imu(path)
    msg = str(e.value)
    assert msg.startswith(f"IMU file {path}, line 2: decimal commas") and "export it with '.' decimals" in msg
    assert "header" not in msg
