"""The second-round battery of bad navigation inputs and interrupted or repeated runs (issue 22, acceptance 4).

Each case: a one-line error naming the flag or file (exit 2), a correct result, or a warning recorded in the
output's metadata. Ctrl-C is simulated deterministically (a step monkeypatched to raise KeyboardInterrupt, or
the ``SystemError`` a numba kernel chains to it) and must end with one line, exit 130 and nothing
complete-looking in ``--out``. The CLI runs in-process on a 150 s simulated drive.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from conftest import one_line_error
from imunoise.cli import build_parser, interrupted, main
from imunoise.errors import DataError
from imunoise.io.atomic import staged_run
from imunoise.io.kfgins import read_gnss, read_imu, write_gnss, write_imu
from imunoise.io.navchecks import check_imu_gaps
from imunoise.sim.drive import DriveConfig, simulate_drive


# ----------------------------------------------------------------------------------------------
# fixtures and helpers
# ----------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def sim(tmp_path_factory) -> dict[str, Path]:
    """A 150 s drive (35 s still, two outage windows) and the bad variants derived from it."""
    cfg = DriveConfig(
        duration_s=150.0,
        n_stops=1,
        static_s=35.0,
        gnss_rate_hz=5.0,
        gnss_sigma_m=(0.05, 0.05, 0.1),
        outages=[(60.0, 20.0), (110.0, 20.0)],
        seed=2,
    )
    root = tmp_path_factory.mktemp("sim")
    d = simulate_drive(cfg, "mems", seed=2).write(root / "drive")
    imu, gnss = read_imu(d / "imu.txt"), read_gnss(d / "gnss.txt")
    bad = root / "bad"
    bad.mkdir()
    rad = np.column_stack([gnss.t, np.degrees(gnss.llh[:, 0:2]), gnss.llh[:, 2], gnss.sigma_ned])
    rad[:, 1:3] = np.radians(rad[:, 1:3])  # the file's "degrees" hold radians
    np.savetxt(bad / "gnss_rad.txt", rad, fmt="%.10f")
    south = np.column_stack([gnss.t, np.degrees(gnss.llh[:, 0:2]), gnss.llh[:, 2], gnss.sigma_ned])
    south[5:, 1] = -105.0
    np.savetxt(bad / "gnss_lat105.txt", south, fmt="%.10f")
    write_gnss(bad / "gnss_unix.txt", type(gnss)(gnss.t + 1.7e9, gnss.llh, gnss.sigma_ned))
    keep = (imu.t < imu.t[0] + 50.0) | (imu.t >= imu.t[0] + 60.0)  # 10 s gap while driving
    write_imu(bad / "imu_gap.txt", type(imu)(imu.t[keep], imu.dtheta[keep], imu.dv[keep]))
    write_imu(bad / "imu_degs.txt", type(imu)(imu.t, np.degrees(imu.dtheta), imu.dv))  # deg read as rad
    return {"dir": d, "imu": d / "imu.txt", "gnss": d / "gnss.txt", "ref": d / "ref.nav", "outages": d / "outages.txt",
            **{p.stem: p for p in bad.iterdir()}}  # fmt: skip


def run_cli(argv: list, capsys) -> tuple[int, str]:
    """Exit code and stderr of one in-process run (argparse refusals exit through SystemExit)."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = int(exc.code or 0)
    return code, capsys.readouterr().err


def files_in(folder: Path) -> list[Path]:
    return sorted(p.relative_to(folder) for p in folder.rglob("*") if p.is_file()) if folder.exists() else []


def nav_argv(sim, out, *extra, imu=None, gnss=None) -> list:
    return ["nav", "--imu", imu or sim["imu"], "--gnss", gnss or sim["gnss"], *extra, "--out", out]


# ----------------------------------------------------------------------------------------------
# navigation inputs
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("cmd", ["nav", "online"])
def test_gnss_in_radians_is_refused_with_the_fix(cmd, sim, tmp_path, capsys):
    out = tmp_path / "o"
    code, err = run_cli([cmd, "--imu", sim["imu"], "--gnss", sim["gnss_rad"], "--out", out], capsys)
    line = one_line_error(code, err, "gnss_rad.txt", "radians", "180/π")
    assert "yaw" not in line  # no longer diagnosed as a missing initial heading
    assert files_in(out) == []


def test_latitude_beyond_90_is_refused_naming_the_line(sim, tmp_path, capsys):
    code, err = run_cli(nav_argv(sim, tmp_path / "o", gnss=sim["gnss_lat105"]), capsys)
    one_line_error(code, err, "gnss_lat105.txt", "line 6", "latitude -105°", "±90°")


def test_imu_gap_is_refused_with_the_flag_that_allows_it(sim, tmp_path, capsys):
    code, err = run_cli(nav_argv(sim, tmp_path / "o", imu=sim["imu_gap"]), capsys)
    one_line_error(code, err, "imu_gap.txt", "10 s time gap", "--max-imu-gap 11", "split the file")
    t = read_imu(sim["imu_gap"]).t
    check_imu_gaps(t, 11.0, "imu_gap.txt")  # the value the message suggests lets it through
    with pytest.raises(DataError, match="--max-imu-gap"):
        check_imu_gaps(t, 9.9, "imu_gap.txt")


def test_gyros_in_deg_s_are_warned_and_recorded(sim, tmp_path, capsys, caplog):
    out = tmp_path / "o"
    code, err = run_cli(nav_argv(sim, out, "--ref", sim["ref"], "--no-plots", imu=sim["imu_degs"]), capsys)
    assert code == 0, err
    notes = json.loads((out / "metrics.json").read_text())["warnings"]
    (note,) = [n for n in notes if "the gyros turn" in n]
    ratio = float(note.split("the gyros turn ")[1].split("×")[0])
    assert 40 < ratio < 75 and "deg/s read as rad/s" in note and "imu_degs.txt" in note
    assert any("the gyros turn" in r.getMessage() for r in caplog.records)  # logged (stderr outside pytest) too


def test_the_true_gyros_raise_no_unit_warning(sim, tmp_path, capsys):
    out = tmp_path / "o"
    code, err = run_cli(nav_argv(sim, out, "--ref", sim["ref"], "--no-plots"), capsys)
    assert code == 0, err
    m = json.loads((out / "metrics.json").read_text())
    assert not any("the gyros turn" in n for n in m["warnings"])
    assert m["horizontal_rms_m"] < 0.5


def test_levelling_over_driving_is_refused_with_the_motion(sim, tmp_path, capsys):
    out = tmp_path / "o"
    code, err = run_cli(nav_argv(sim, out, "--static-duration", 80), capsys)
    line = one_line_error(code, err, "--static-duration 80", "not still", "2λ0", "give the length of the stop")
    first = float(line.split("first at ")[1].split(" s")[0])
    assert 30.0 < first < 40.0  # the simulated drive leaves its 35 s stop
    assert files_in(out) == []


def test_simulate_start_latitude_95_is_refused(tmp_path, capsys):
    out = tmp_path / "o"
    code, err = run_cli(["simulate", "--start-llh", 95, 0, 0, "--duration", 60, "--out", out], capsys)
    one_line_error(code, err, "--start-llh", "latitude 95°", "±90°")
    assert files_in(out) == []


def test_different_time_bases_name_both_ranges(sim, tmp_path, capsys):
    code, err = run_cli(nav_argv(sim, tmp_path / "o", gnss=sim["gnss_unix"]), capsys)
    line = one_line_error(code, err, "different time bases", "imu.txt", "gnss_unix.txt", "--imu-time-offset")
    assert "--start" not in line  # no --start was given
    assert "[100000." in line and "[1700100000." in line


def test_online_takes_yaw_like_nav(sim, tmp_path, capsys, monkeypatch):
    """`online --yaw 30` reaches the alignment as 30° (the run is stopped right there)."""
    import imunoise.nav.align as align

    seen = {}

    def stop(*a, **kw):
        seen.update(kw)
        raise DataError("stopped after the alignment's arguments")

    monkeypatch.setattr(align, "coarse_align", stop)
    for cmd in ("nav", "online"):
        code, err = run_cli([cmd, "--data", sim["dir"], "--yaw", 30, "--out", tmp_path / cmd], capsys)
        one_line_error(code, err, "stopped after")
        assert seen.pop("yaw") == pytest.approx(math.radians(30.0))


@pytest.mark.parametrize("cmd", ["nav", "online"])
@pytest.mark.parametrize(
    ("flag", "values"),
    [("--lever-arm", ["0", "nan", "0"]), ("--yaw", ["nan"]), ("--imu-time-offset", ["nan"]), ("--start", ["inf"])],
)
def test_non_finite_numbers_are_refused_at_parse_time(cmd, flag, values, sim, tmp_path, capsys):
    out = tmp_path / "o"
    code, err = run_cli([cmd, "--data", sim["dir"], flag, *values, "--out", out], capsys)
    one_line_error(code, err, f"argument {flag}", "must be a finite number")
    assert not out.exists()


def test_every_float_option_of_every_command_refuses_nan():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    checked = 0
    for sp in sub.choices.values():
        for a in sp._actions:
            if a.type is not None and "float" in getattr(a.type, "__name__", ""):
                for bad in ("nan", "inf", "-inf"):
                    with pytest.raises(Exception, match="finite"):
                        a.type(bad)
                checked += 1
    assert checked > 40


@pytest.mark.parametrize(
    ("argv", "flag"),
    [
        (["nav", "--cov-every", "0"], "--cov-every"),
        (["nav", "--cov-every", "-1"], "--cov-every"),
        (["detect", "--speed-threshold", "-1"], "--speed-threshold"),
        (["experiment", "online", "--workers", "0"], "--workers"),
        (["demo", "--workers", "0"], "--workers"),
        (["online", "--min-static", "0"], "--min-static"),
        (["detect", "--window", "1"], "--window"),
        (["nav", "--static-duration", "0"], "--static-duration"),
        (["nav", "--max-imu-gap", "-1"], "--max-imu-gap"),
    ],
)
def test_impossible_counts_and_thresholds_are_refused(argv, flag, tmp_path, capsys):
    code, err = run_cli([*argv, "--out", tmp_path / "o"], capsys)
    one_line_error(code, err, f"argument {flag}")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    ("message", "said"),
    [
        ("min_static_s must be > 0 s, got 0", "--min-static must be > 0 s"),
        ("DetectorConfig.window must be a whole number of samples ≥ 2 (paper: 100), got 1", "--window must be"),
    ],
)
def test_errors_name_the_flag_not_the_python_field(message, said, tmp_path, capsys, monkeypatch):
    """A library message that names a Python field reaches the user with the flag that sets it."""
    import imunoise.cli.detect as detect
    from imunoise.errors import ModelError

    def fail(args):
        raise ModelError(message)

    monkeypatch.setattr(detect, "run", fail)  # registered afresh by main(): the handler raises the message
    code, err = run_cli(["detect", "--imu", "x", "--out", tmp_path / "o"], capsys)
    line = one_line_error(code, err, said)
    assert "min_static_s" not in line and "DetectorConfig" not in line


# ----------------------------------------------------------------------------------------------
# interrupted and repeated runs
# ----------------------------------------------------------------------------------------------
def _interrupt_on_call(n: int, exc: BaseException):
    """A replacement of ``run_ekf`` that runs the real one n − 1 times, then raises ``exc``."""
    from imunoise.nav import ekf

    real = ekf.run_ekf
    calls = {"n": 0}

    def fake(*a, **kw):
        calls["n"] += 1
        if calls["n"] >= n:
            raise exc
        return real(*a, **kw)

    return fake


@pytest.mark.parametrize(
    "exc",
    [KeyboardInterrupt(), SystemError("<built-in function kernel> returned a result with an exception set")],
    ids=["KeyboardInterrupt", "numba-SystemError-chain"],
)
def test_ctrl_c_during_outage_runs_leaves_nothing_complete_looking(exc, sim, tmp_path, capsys, monkeypatch):
    from imunoise.nav import ekf

    if isinstance(exc, SystemError):
        exc.__cause__ = KeyboardInterrupt()  # what a Ctrl-C inside a numba kernel looks like
    monkeypatch.setattr(ekf, "run_ekf", _interrupt_on_call(3, exc))  # full run, outage 1, Ctrl-C in outage 2
    out = tmp_path / "o"
    code, err = run_cli(["nav", "--data", sim["dir"], "--outage-runs", "--no-plots", "--out", out], capsys)
    assert code == 130
    assert err.strip().splitlines()[-1] == "imunoise nav: interrupted (Ctrl-C)"
    assert "Traceback" not in err and "SystemError" not in err
    assert files_in(out) == []
    assert [p.name for p in tmp_path.iterdir()] == ["o"]  # no staging folder left beside it


def test_ctrl_c_during_online_leaves_nothing(sim, tmp_path, capsys, monkeypatch):
    from imunoise.online import OnlineNavigator

    def stop(self, *a, **kw):
        raise KeyboardInterrupt

    monkeypatch.setattr(OnlineNavigator, "run", stop)
    out = tmp_path / "o"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    code, err = run_cli(["online", "--data", sim["dir"], "--out", out], capsys)
    assert code == 130 and err.strip().splitlines()[-1] == "imunoise online: interrupted (Ctrl-C)"
    assert files_in(out) == [Path("notes.txt")]


def test_interrupted_recognises_chains():
    inner = KeyboardInterrupt()
    wrapped = SystemError("kernel")
    wrapped.__context__ = inner
    outer = RuntimeError("outer")
    outer.__cause__ = wrapped
    assert interrupted(outer) and interrupted(inner)
    assert not interrupted(SystemError("a real bug"))


def test_rerun_in_the_same_folder_removes_the_earlier_runs_files_only(sim, tmp_path, capsys):
    out = tmp_path / "o"
    code, err = run_cli(["nav", "--data", sim["dir"], "--outage-runs", "--out", out], capsys)
    assert code == 0, err
    first = set(files_in(out))
    assert {Path("outage_1/metrics.json"), Path("outage_2/trajectory.nav"), Path("errors.png")} <= first
    (out / "imu_model.json").write_text("{}")  # another command's output
    (out / "outage_1" / "my_notes.txt").write_text("keep")  # the user's file in a folder nav writes
    code, err = run_cli(["nav", "--data", sim["dir"], "--outages", sim["outages"], "--no-plots", "--out", out], capsys)
    assert code == 0, err
    assert set(files_in(out)) == {
        Path("trajectory.nav"), Path("metrics.json"), Path("imu_model.json"), Path("outage_1/my_notes.txt")
    }
    m = json.loads((out / "metrics.json").read_text())
    assert len(m["outages"]) == 2 and all(o["duration"] == 20.0 for o in m["outages"])  # windows in one run


def test_staged_run_publishes_all_or_nothing(tmp_path):
    out = tmp_path / "o"
    with pytest.raises(KeyboardInterrupt):
        with staged_run(out, ["a.txt"]) as stage:
            (stage / "a.txt").write_text("new")
            raise KeyboardInterrupt
    assert files_in(out) == []
    with staged_run(out, ["a.txt", "sub/*.txt"]) as stage:
        (stage / "sub").mkdir()
        (stage / "sub" / "b.txt").write_text("b")
    with staged_run(out, ["a.txt", "sub/*.txt"]) as stage:
        (stage / "a.txt").write_text("a")
    assert files_in(out) == [Path("a.txt")]
    assert not (out / "sub").exists()


def test_ctrl_c_inside_the_em_kernel_is_one_line(tmp_path, capsys, monkeypatch):
    """A Ctrl-C inside a numba kernel reaches Python as a SystemError chained to the KeyboardInterrupt."""
    import imunoise.noise.em as em

    def kernel_interrupted(*a, **kw):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise SystemError("<numba kernel> returned a result with an exception set") from None

    monkeypatch.setattr(em, "em_fit", kernel_interrupted)
    data = tmp_path / "x.csv"
    np.savetxt(data, 1e-3 * np.random.default_rng(0).standard_normal(2000), header="gyro_x", comments="")
    out = tmp_path / "o"
    code, err = run_cli(["em", data, "--freq", 100, "--model", "WN", "--out", out], capsys)
    assert code == 130 and err.strip().splitlines() == ["imunoise em: interrupted (Ctrl-C)"]
    assert not (out / "model.json").exists()


def test_levelling_window_with_moving_gnss_is_refused():
    """Still accelerometers (a smooth start) but a GNSS antenna 40 m away by the end of the window: refused."""
    from imunoise.io.kfgins import GnssData
    from imunoise.nav.align import check_static_window

    t = np.arange(0.0, 30.0, 0.01)
    accel = np.tile([0.0, 0.0, -9.81], (t.size, 1)) + 1e-3 * np.random.default_rng(1).standard_normal((t.size, 3))
    tg = np.arange(0.0, 31.0, 1.0)
    north = np.where(tg > 20.0, 4.0 * (tg - 20.0), 0.0)  # starts rolling at 20 s, 4 m/s
    llh = np.column_stack([np.radians(40.0) + north / 6.37e6, np.full(tg.size, np.radians(-105.0)), np.zeros(tg.size)])
    gnss = GnssData(tg, llh, np.full((tg.size, 3), 0.05))
    moving = r"--static-duration 30: the GNSS antenna moves 40 m inside .*beyond 10 m at 23\.0 s"
    with pytest.raises(DataError, match=moving):
        check_static_window(t, accel, gnss, 0.0, 30.0)
    check_static_window(t, accel, gnss, 0.0, 20.0)  # the still part passes
