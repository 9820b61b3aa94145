"""Every bad input: one line on stderr naming the file/option, exit 2, no traceback, nothing written that
looks complete (issue "Trustworthy outputs" §3). The CLI runs in-process (``imunoise.cli.main``); the
drive cases use a 45 s slice of the shipped data/drive_0708 so that each case stays fast."""

from __future__ import annotations

import gzip
import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from imunoise.cli import build_parser, main
from imunoise.errors import DataError
from imunoise.io.atomic import atomic_path, atomic_write_text, staged_dir
from imunoise.io.imu_input import read_imu_source
from imunoise.io.tabular import UnitWarning

REPO = Path(__file__).resolve().parents[2]
DRIVE = REPO / "data" / "drive_0708"
JUNK = bytes(range(256)) * 8 + b"\x00\xff\xfe" * 100  # binary junk: NUL and invalid UTF-8


# ----------------------------------------------------------------------------------------------
# fixtures
# ----------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def drive(tmp_path_factory) -> dict[str, Path]:
    """45 s of drive_0708 (34.5 s still, then driving) as plain files, and the derived bad inputs."""
    d = tmp_path_factory.mktemp("drive")
    with gzip.open(DRIVE / "imu_body_inc.txt.gz", "rt") as fh:
        lines = [next(fh) for _ in range(4500)]
    (d / "imu.txt").write_text("".join(lines))
    (d / "imu15.txt").write_text("".join(lines[:15]))
    gnss = (DRIVE / "gnss_rtk.txt").read_text().splitlines(keepends=True)
    (d / "gnss.txt").write_text("".join(gnss[:400]))
    with gzip.open(DRIVE / "ref_rtk.nav.gz", "rt") as fh:
        (d / "ref.nav").write_text("".join(next(fh) for _ in range(400)))
    raw = gzip.compress("".join(lines).encode())
    (d / "imu_trunc.txt.gz").write_bytes(raw[: len(raw) // 2])
    (d / "outside.txt").write_text("# start duration\n250000.0 60\n")
    (d / "junk.bin").write_bytes(JUNK)
    return {p.stem if p.suffix != ".gz" else p.name: p for p in d.iterdir()} | {"dir": d}


@pytest.fixture(scope="module")
def static(tmp_path_factory) -> dict[str, Path]:
    """A small static gyro table (rad/s, 100 Hz) and its broken variants."""
    d = tmp_path_factory.mktemp("static")
    rng = np.random.default_rng(0)
    x = 1e-3 * rng.standard_normal(3000)
    np.savetxt(d / "ok.csv", x, header="gyro_x", comments="")
    text = "gyro_x\n" + "\n".join(f"{v:.9e}" for v in x) + "\n"
    raw = gzip.compress(text.encode())
    (d / "trunc.csv.gz").write_bytes(raw[: len(raw) // 2])
    for name in ("junk.csv", "junk.txt", "junk.npy", "junk.npz", "junk.bag", "junk.mcap"):
        (d / name).write_bytes(JUNK)
    np.save(d / "pickled.npy", np.array([{"a": 1}, None], dtype=object), allow_pickle=True)
    np.save(d / "full.npy", x)
    (d / "trunc.npy").write_bytes((d / "full.npy").read_bytes()[:1000])
    np.savez(d / "full.npz", data=x[:, None])
    (d / "trunc.npz").write_bytes((d / "full.npz").read_bytes()[:1000])
    (d / "notgzip.csv.gz").write_text(text)
    (d / "model.bin").write_bytes(JUNK)
    return {p.name: p for p in d.iterdir()}


def run_cli(argv: list[str], capsys) -> tuple[int, str]:
    """Exit code and stderr of one in-process run; a value refused at parse time exits through argparse."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = int(exc.code or 0)
    err = capsys.readouterr().err
    return code, err


def assert_one_line_error(code: int, err: str, *names: str) -> str:
    """Exit 2, exactly one 'error:' line, naming every string in ``names``, and no traceback."""
    assert code == 2, err
    assert "Traceback" not in err
    errors = [ln for ln in err.splitlines() if ": error: " in ln]
    assert len(errors) == 1, err
    for name in names:
        assert str(name) in errors[0], (name, errors[0])
    return errors[0]


def files_in(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if p.is_file()] if folder.exists() else []


# ----------------------------------------------------------------------------------------------
# unreadable inputs of the static commands
# ----------------------------------------------------------------------------------------------
STATIC_CMDS = {
    "fit": ["--model", "WN"],
    "select": [],
    "allan": [],
    "em": ["--model", "WN"],
    "compare": [],
}


@pytest.mark.parametrize("cmd", list(STATIC_CMDS))
@pytest.mark.parametrize("bad", ["junk.csv", "trunc.csv.gz"])
def test_static_commands_refuse_junk_and_truncated_gzip(cmd, bad, static, tmp_path, capsys):
    out = tmp_path / "out"
    code, err = run_cli([cmd, static[bad], "--freq", 100, *STATIC_CMDS[cmd], "--out", out], capsys)
    assert_one_line_error(code, err, bad)
    assert files_in(out) == []


@pytest.mark.parametrize(
    "bad",
    ["junk.txt", "junk.npy", "junk.npz", "pickled.npy", "trunc.npy", "trunc.npz", "notgzip.csv.gz", "junk.bag",
     "junk.mcap"],
)
def test_fit_refuses_binary_and_pickled_files(bad, static, tmp_path, capsys):
    out = tmp_path / "out"
    code, err = run_cli(["fit", static[bad], "--freq", 100, "--model", "WN", "--out", out], capsys)
    line = assert_one_line_error(code, err, bad)
    if bad.endswith((".npy", ".npz")):
        assert "NumPy" in line
    assert files_in(out) == []


@pytest.mark.parametrize(
    "bad", ["junk.csv", "junk.npy", "junk.npz", "pickled.npy", "trunc.npy", "trunc.npz", "junk.bag"]
)
def test_fit_stream_refuses_binary_and_pickled_files(bad, static, tmp_path, capsys):
    out = tmp_path / "out"
    code, err = run_cli(["fit", static[bad], "--freq", 100, "--model", "WN", "--stream", "--out", out], capsys)
    line = assert_one_line_error(code, err, bad)
    if bad.endswith((".npy", ".npz")):
        assert "NumPy" in line
    assert files_in(out) == []


@pytest.mark.parametrize(
    "extra, names",
    [(["--robust"], ["--stream", "--robust"]), (["--max-scale", "0"], ["--max-scale"])],
)
def test_fit_stream_options_that_cannot_stream(extra, names, static, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["fit", static["ok.csv"], "--freq", 100, "--model", "WN", "--stream", *extra, "--out", out]
    code, err = run_cli(argv, capsys)
    assert_one_line_error(code, err, *names)
    assert files_in(out) == []


def test_em_init_binary_file(static, tmp_path, capsys):
    out = tmp_path / "out"
    code, err = run_cli(
        ["em", static["ok.csv"], "--freq", 100, "--model", "WN", "--init", static["model.bin"], "--out", out], capsys
    )
    assert_one_line_error(code, err, "--init", "model.bin")
    assert files_in(out) == []


# ----------------------------------------------------------------------------------------------
# unusable --out, every writing command
# ----------------------------------------------------------------------------------------------
def writing_commands(static: dict, drive: dict, tmp: Path) -> dict[str, list]:
    nav_in = ["--imu", drive["imu"], "--gnss", drive["gnss"]]
    return {
        "fit": ["fit", static["ok.csv"], "--freq", 100, "--model", "WN"],
        "select": ["select", static["ok.csv"], "--freq", 100],
        "allan": ["allan", static["ok.csv"], "--freq", 100],
        "em": ["em", static["ok.csv"], "--freq", 100, "--model", "WN"],
        "compare": ["compare", static["ok.csv"], "--freq", 100],
        "nav": ["nav", *nav_in],
        "online": ["online", *nav_in],
        "detect": ["detect", "--imu", drive["imu"]],
        "calibrate": ["calibrate", drive["imu"]],
        "simulate": ["simulate", "--duration", 60],
        "batch": ["batch", str(static["ok.csv"]), "--freq", 100, "--model", "WN", "--scheduler", "sequential"],
        "demo": ["demo", "--static"],
        "experiment": ["experiment", "online"],
    }


@pytest.mark.parametrize(
    "cmd", ["fit", "select", "allan", "em", "compare", "nav", "online", "detect", "simulate", "batch", "demo",
            "experiment", "calibrate"]
)
@pytest.mark.parametrize("kind", ["existing_file", "proc", "under_file"])
def test_unusable_out_is_one_line(cmd, kind, static, drive, tmp_path, capsys):
    blocker = tmp_path / "taken"
    blocker.write_text("keep me\n")
    out = {"existing_file": blocker, "proc": Path("/proc/imunoise_out"), "under_file": blocker / "sub"}[kind]
    if kind == "proc" and not Path("/proc").is_dir():
        pytest.skip("no /proc on this system")
    argv = writing_commands(static, drive, tmp_path)[cmd] + ["--out", out]
    code, err = run_cli(argv, capsys)
    line = assert_one_line_error(code, err, "--out", out)
    assert "not found" not in line  # an output is never reported as a missing input
    assert blocker.read_text() == "keep me\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken"]


# ----------------------------------------------------------------------------------------------
# navigation inputs
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("cmd", ["nav", "online", "detect"])
def test_truncated_gzip_imu(cmd, drive, tmp_path, capsys):
    out = tmp_path / "out"
    argv = [cmd, "--imu", drive["imu_trunc.txt.gz"], "--out", out]
    if cmd != "detect":
        argv += ["--gnss", drive["gnss"]]
    code, err = run_cli(argv, capsys)
    line = assert_one_line_error(code, err, "imu_trunc.txt.gz")
    assert "truncated" in line or "ends early" in line
    assert files_in(out) == []


@pytest.mark.parametrize("cmd", ["nav", "online"])
@pytest.mark.parametrize("which", ["imu", "gnss", "ref", "outages", "model"])
def test_nav_binary_input_files(cmd, which, drive, tmp_path, capsys):
    out = tmp_path / "out"
    files = {"imu": drive["imu"], "gnss": drive["gnss"], which: drive["junk"]}
    argv = [cmd, "--imu", files["imu"], "--gnss", files["gnss"], "--out", out]
    if which in ("ref", "outages", "model"):
        argv += [f"--{which}", drive["junk"]]
    code, err = run_cli(argv, capsys)
    assert_one_line_error(code, err, "junk.bin")
    assert files_in(out) == []


def test_dataset_manifest_binary(drive, tmp_path, capsys):
    folder = tmp_path / "ds"
    folder.mkdir()
    (folder / "dataset.json").write_bytes(JUNK)
    code, err = run_cli(["nav", "--data", folder, "--out", tmp_path / "out"], capsys)
    assert_one_line_error(code, err, "dataset.json")
    code, err = run_cli(["detect", "--data", folder, "--out", tmp_path / "out"], capsys)
    assert_one_line_error(code, err, "dataset.json")


@pytest.mark.parametrize("cmd", ["nav", "online"])
def test_outage_window_outside_the_data(cmd, drive, tmp_path, capsys):
    out = tmp_path / "out"
    argv = [cmd, "--imu", drive["imu"], "--gnss", drive["gnss"], "--outages", drive["outside"], "--out", out]
    code, err = run_cli(argv, capsys)
    assert_one_line_error(code, err, "outside.txt", "250000")
    assert files_in(out) == []


@pytest.mark.parametrize("cmd", ["nav", "online"])
def test_fifteen_sample_imu(cmd, drive, tmp_path, capsys):
    out = tmp_path / "out"
    code, err = run_cli([cmd, "--imu", drive["imu15"], "--gnss", drive["gnss"], "--out", out], capsys)
    assert_one_line_error(code, err, "imu15.txt", "15 samples")
    assert files_in(out) == []


@pytest.mark.parametrize(
    ("extra", "named"),
    [
        (["--learn-from", 0], "--learn-from"),
        (["--learn-from", -5], "--learn-from"),
        (["--learn-from", 1e6], "--learn-from"),
        (["--learn-from", 1], "--learn-from"),  # 100 samples < 2 × the 100-sample window
        (["--learn-from", 40, "--ref", "REF"], "not a stop"),  # the car drives off at 34.5 s
        (["--lambda0", 0], "--lambda0"),
        (["--lambda0", -0.1], "--lambda0"),
    ],
)
def test_online_lambda0_options(extra, named, drive, tmp_path, capsys):
    out = tmp_path / "out"
    extra = [drive["ref"] if e == "REF" else e for e in extra]
    argv = ["online", "--imu", drive["imu"], "--gnss", drive["gnss"], *extra, "--out", out]
    code, err = run_cli(argv, capsys)
    assert_one_line_error(code, err, named)
    assert files_in(out) == []


@pytest.mark.parametrize(
    ("extra", "named"),
    [
        (["--learn-from", 1e6], "--learn-from"),
        (["--learn-from", 0], "--learn-from"),
        (["--learn-from", 40, "--ref", "REF"], "not a stop"),
        (["--lambda0", 0], "--lambda0"),
    ],
)
def test_detect_lambda0_options(extra, named, drive, tmp_path, capsys):
    out = tmp_path / "out"
    extra = [drive["ref"] if e == "REF" else e for e in extra]
    code, err = run_cli(["detect", "--imu", drive["imu"], *extra, "--out", out], capsys)
    assert_one_line_error(code, err, named)
    assert files_in(out) == []


def test_detect_warns_when_nearly_everything_is_static(drive, tmp_path, capsys):
    """λ0 = 5 m/s² calls the whole slice static: the run is kept, the warning printed and recorded."""
    out = tmp_path / "out"
    code, err = run_cli(["detect", "--imu", drive["imu"], "--lambda0", 5, "--out", out], capsys)
    assert code == 0, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["static_time_s"] > 0.9 * summary["duration_s"]
    assert any("called static" in w for w in summary["warnings"])
    assert "warning:" in err and "called static" in err


def test_missing_input_subprocess(tmp_path):
    """The real console entry point: one line, exit 2, no traceback (as a user sees it)."""
    junk = tmp_path / "junk.csv"
    junk.write_bytes(JUNK)
    r = subprocess.run(
        [sys.executable, "-m", "imunoise", "select", str(junk), "--freq", "100", "--out", str(tmp_path / "o")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert r.stderr.strip().count("\n") == 0 and "junk.csv" in r.stderr


# ----------------------------------------------------------------------------------------------
# units and rate from the file; loud warning for data that cannot be SI
# ----------------------------------------------------------------------------------------------
def test_adis_npz_read_with_its_freq_and_units(shared_data):
    path = shared_data("imudata_adis16405", "adis16405_unit1.npz")
    series = read_imu_source(path, columns=["gyro_x", "accel_z"])
    with np.load(path) as z:
        raw = z["data"]
    assert series.freq == 100.0
    assert series.unit == {"gyro_x": "rad/s", "accel_z": "m/s²"}
    assert series.source_unit == {"gyro_x": "deg/s", "accel_z": "g"}
    np.testing.assert_array_equal(series.data["gyro_x"], np.deg2rad(raw[:, 0]))
    np.testing.assert_allclose(series.data["accel_z"], raw[:, 5] * 9.80665, rtol=1e-15)
    assert series.meta.get("units_from_file") and not series.meta.get("warnings")
    with pytest.raises(DataError, match="100 Hz but --freq is 200"):
        read_imu_source(path, columns=["gyro_x"], freq=200.0)


def test_npz_units_reach_the_fit_output(tmp_path, capsys):
    rng = np.random.default_rng(1)
    x = 0.3 + 0.2 * rng.standard_normal(4000)  # deg/s, like the ADIS gyros
    path = tmp_path / "g.npz"
    np.savez(path, data=x[:, None], columns=np.array(["gyro_x"]), units=np.array(["deg/s"]), freq_hz=200.0)
    out = tmp_path / "fit"
    code, err = run_cli(["fit", path, "--model", "WN", "--out", out], capsys)
    assert code == 0, err
    fit = json.loads((out / "model.json").read_text())
    assert fit["freq_hz"] == 200.0
    assert fit["unit"] == "rad/s" and fit["extra"]["source_unit"] == "deg/s"
    # WN σ² of the SI data: the deg/s variance times (π/180)²
    assert fit["params"]["WN.sigma2"] == pytest.approx(np.var(np.deg2rad(x)), rel=0.05)
    assert "warning" not in err


def test_deg_s_without_units_warns_loudly(tmp_path, capsys):
    rng = np.random.default_rng(2)
    x = 0.5 + 0.3 * rng.standard_normal(4000)  # a static gyro in deg/s, given without --units
    path = tmp_path / "gyro.csv"
    np.savetxt(path, x, header="gyro_x", comments="")
    with pytest.warns(UnitWarning, match="--units deg/s"):
        read_imu_source(path, freq=100.0)
    out = tmp_path / "fit"
    code, err = run_cli(["fit", path, "--freq", 100, "--model", "WN", "--out", out], capsys)
    assert code == 0
    assert "warning:" in err and "--units deg/s" in err
    fit = json.loads((out / "model.json").read_text())
    assert fit["unit"] == "u"
    assert any("--units deg/s" in w for w in fit["extra"]["warnings"])
    # the same data with --units: no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnitWarning)
        read_imu_source(path, freq=100.0, units="deg/s")


def test_accelerometers_in_g_without_units_warn(tmp_path):
    rng = np.random.default_rng(3)
    a = 1e-3 * rng.standard_normal((2000, 3)) + np.array([0.01, 0.01, -1.0])  # a level IMU in g
    path = tmp_path / "acc.csv"
    np.savetxt(path, a, delimiter=",", header="accel_x,accel_y,accel_z", comments="")
    with pytest.warns(UnitWarning, match="accel=g"):
        read_imu_source(path, freq=100.0)


# ----------------------------------------------------------------------------------------------
# shared options (section 4)
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("cmd", ["fit", "select", "allan", "em", "compare", "batch"])
def test_time_unit_choices_are_the_same_everywhere(cmd):
    parser = build_parser()
    extra = {"fit": ["--model", "WN"], "em": ["--model", "WN"], "batch": ["--model", "WN", "--out", "o"]}
    for unit in ("s", "ms", "us", "µs", "ns"):
        args = parser.parse_args([cmd, "x.csv", *extra.get(cmd, []), "--time-unit", unit])
        assert args.time_unit == unit


@pytest.mark.parametrize("cmd", ["fit", "select", "compare", "batch", "online"])
def test_default_ranking_is_wvic_everywhere(cmd):
    argv = {
        "fit": ["fit", "x.csv", "--auto"],
        "select": ["select", "x.csv"],
        "compare": ["compare", "x.csv"],
        "batch": ["batch", "x.csv", "--auto", "--out", "o"],
        "online": ["online", "--out", "o"],
    }[cmd]
    args = build_parser().parse_args(argv)
    assert args.criterion == "wvic"
    assert build_parser().parse_args([*argv, "--criterion", "gof"]).criterion == "gof"


def test_simulate_default_out_is_git_ignored():
    args = build_parser().parse_args(["simulate"])
    assert args.out == Path("out/simulate")
    assert "out/" in (REPO / ".gitignore").read_text().splitlines()


# ----------------------------------------------------------------------------------------------
# atomic writes
# ----------------------------------------------------------------------------------------------
def test_atomic_write_leaves_nothing_on_error(tmp_path):
    target = tmp_path / "model.json"
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text('{"half": ')
            raise RuntimeError("interrupted")
    assert list(tmp_path.iterdir()) == []
    # an existing file is kept as it was
    atomic_write_text(target, "old\n")
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(target) as tmp:
            tmp.write_text("new, half")
            raise KeyboardInterrupt
    assert target.read_text() == "old\n"
    assert [p.name for p in tmp_path.iterdir()] == ["model.json"]


def test_staged_dir_moves_all_or_nothing(tmp_path):
    out = tmp_path / "sim"
    with pytest.raises(RuntimeError):
        with staged_dir(out) as stage:
            (stage / "imu.txt").write_text("complete\n")
            raise RuntimeError("no truth")
    assert not out.exists() and list(tmp_path.iterdir()) == []
    with staged_dir(out) as stage:
        (stage / "imu.txt").write_text("complete\n")
        (stage / "truth.json").write_text("{}\n")
    assert sorted(p.name for p in out.iterdir()) == ["imu.txt", "truth.json"]
    assert list(tmp_path.iterdir()) == [out]


def test_interrupted_simulate_leaves_no_imu_file(tmp_path, capsys, monkeypatch):
    """Interrupted after imu.txt and before the truth (as Ctrl-C would): no complete-looking imu.txt."""
    import imunoise.sim.drive as drive_mod

    def interrupted(*_a, **_k):
        raise KeyboardInterrupt

    monkeypatch.setattr(drive_mod, "write_reference", interrupted)
    out = tmp_path / "sim"
    code, err = run_cli(["simulate", "--duration", 70, "--stops", 0, "--static-start", 10, "--out", out], capsys)
    assert code == 130, err
    assert files_in(tmp_path) == []  # not even a hidden staging file
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    monkeypatch.undo()
    code, err = run_cli(["simulate", "--duration", 70, "--stops", 0, "--static-start", 10, "--out", out], capsys)
    assert code == 0, err
    assert {"imu.txt", "gnss.txt", "ref.nav", "truth.json", "dataset.json"} <= {p.name for p in out.iterdir()}


def test_outage_cut_by_the_end_of_data_is_a_recorded_warning(drive, tmp_path, capsys):
    """A window that starts inside the data but ends after it still gives a meaningful run: kept, warned
    and recorded in metrics.json."""
    windows = tmp_path / "late.txt"
    windows.write_text("243300.0 60\n")
    out = tmp_path / "out"
    argv = ["nav", "--imu", drive["imu"], "--gnss", drive["gnss"], "--outages", windows, "--no-plots", "--out", out]
    code, err = run_cli(argv, capsys)
    assert code == 0, err
    metrics = json.loads((out / "metrics.json").read_text())
    assert any("ends after the data" in w and "late.txt" in w for w in metrics["warnings"])
