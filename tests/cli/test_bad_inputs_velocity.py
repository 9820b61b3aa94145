"""Bad GNSS velocity inputs (issue 34): each a one-line error naming the option or file and the fix (exit 2) or a
correct result with the dropped fixes counted in metrics.json. The CLI runs in-process on a 150 s simulated drive
whose antenna velocity (the simulator's truth + 5 cm/s noise) is written as `t vN vE vD σN σE σD`."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from conftest import one_line_error
from imunoise.cli import main
from imunoise.errors import DataError
from imunoise.nav.measurements.gnss_velocity import as_gnss_velocity
from imunoise.sim.drive import DriveConfig, simulate_drive


@pytest.fixture(scope="module")
def sim(tmp_path_factory) -> dict[str, Path]:
    cfg = DriveConfig(duration_s=150.0, n_stops=1, static_s=35.0, gnss_rate_hz=5.0, gnss_sigma_m=(0.05, 0.05, 0.1),
                      outages=[(60.0, 20.0), (110.0, 20.0)], seed=2)
    root = tmp_path_factory.mktemp("vel")
    drive = simulate_drive(cfg, "mems", seed=2)
    d = drive.write(root / "drive")
    a = drive.reference_antenna
    t = np.arange(a.t[0] + 1.0, a.t[-1] - 1.0, 0.25)
    v = np.column_stack([np.interp(t, a.t, a.vel_ned[:, i]) for i in range(3)])
    v += np.random.default_rng(5).normal(0.0, 0.05, v.shape)
    s = np.full_like(v, 0.05)

    def write(name, tt=t, vv=v, ss=s):
        p = root / name
        np.savetxt(p, np.column_stack([tt, vv, ss]), fmt="%.6f", header="t vN vE vD sN sE sD")
        return p

    nan = v.copy()
    nan[10:17] = np.nan
    neg = s.copy()
    neg[40] = -0.05
    files = {"good": write("vel.txt"), "nan": write("vel_nan.txt", vv=nan), "neg": write("vel_neg.txt", ss=neg),
             "unix": write("vel_unix.txt", tt=t + 1.7e9), "kmh": write("vel_kmh.txt", vv=v * 3.6)}
    p = root / "vel_2col.txt"
    np.savetxt(p, np.column_stack([t, v[:, :2]]), fmt="%.6f")
    files["two"] = p
    return {"imu": d / "imu.txt", "gnss": d / "gnss.txt", "ref": d / "ref.nav", "outages": d / "outages.txt", **files}


def run_cli(argv: list, capsys) -> tuple[int, str]:
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = int(exc.code or 0)
    return code, capsys.readouterr().err


def nav(sim, out, vel) -> list:
    return ["nav", "--imu", sim["imu"], "--gnss", sim["gnss"], "--ref", sim["ref"], "--outages", sim["outages"],
            "--gnss-vel", vel, "--no-plots", "--out", out]


def test_velocity_aids_through_the_outages_and_is_counted(sim, tmp_path, capsys):
    code, err = run_cli(nav(sim, tmp_path / "v", sim["good"]), capsys)
    assert code == 0, err
    m = json.loads((tmp_path / "v" / "metrics.json").read_text())
    code, err = run_cli(["nav", "--imu", sim["imu"], "--gnss", sim["gnss"], "--ref", sim["ref"], "--outages",
                         sim["outages"], "--no-plots", "--out", tmp_path / "p"], capsys)
    assert code == 0, err
    m0 = json.loads((tmp_path / "p" / "metrics.json").read_text())
    g = m["gnss_vel"]
    assert g["fixes"] == g["used"] + g["rejected"] + g["forced"] + g["outside_run"] + g["dropped_nan"]
    assert g["in_outages"]["used"] + g["in_outages"]["forced"] > 0.9 * 160  # 2 × 20 s at 4 Hz
    assert m["horizontal_rms_m"] < 0.5 * m0["horizontal_rms_m"], (m["horizontal_rms_m"], m0["horizontal_rms_m"])


def test_nan_velocities_are_dropped_and_counted(sim, tmp_path, capsys):
    code, err = run_cli(nav(sim, tmp_path / "o", sim["nan"]), capsys)
    assert code == 0, err
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert m["gnss_vel"]["dropped_nan"] == 7
    assert any("7 rows with NaN dropped" in w and "vel_nan.txt" in w for w in m["warnings"])


@pytest.mark.parametrize("case,words", [
    ("neg", ["vel_neg.txt", "--gnss-vel", "not positive", "row 41"]),
    ("unix", ["vel_unix.txt", "--gnss-vel", "Unix time", "convert them to GPS seconds of week"]),
    ("kmh", ["vel_kmh.txt", "--gnss-vel", "km/h", "divide by 3.6"]),
    ("two", ["vel_2col.txt", "--gnss-vel", "3 columns", "expected 4"]),
])
def test_bad_velocity_files_are_refused_in_one_line(sim, tmp_path, capsys, case, words):
    out = tmp_path / "o"
    code, err = run_cli(nav(sim, out, sim[case]), capsys)
    one_line_error(code, err, *words)
    assert not out.exists() or not any(out.iterdir())


def test_bad_velocity_arrays_are_refused_by_the_api():
    t = np.arange(5.0)
    with pytest.raises(DataError, match=r"expected \(n, 3\) North, East, Down"):
        as_gnss_velocity(t, np.zeros((5, 2)), 0.05)
    with pytest.raises(DataError, match="negative σ"):
        as_gnss_velocity(t, np.zeros((5, 3)), [0.05, -0.05, 0.05])
    v = as_gnss_velocity(t, np.where(t[:, None] == 2, np.nan, 1.0) * np.ones((5, 3)), 0.05)
    assert v.t.size == 4 and v.dropped == 1


def test_gnss_vel_without_a_file_needs_a_manifest(sim, tmp_path, capsys):
    code, err = run_cli(["nav", "--imu", sim["imu"], "--gnss", sim["gnss"], "--gnss-vel", "--out", tmp_path / "o"],
                        capsys)
    one_line_error(code, err, "--gnss-vel", "gnss_vel")
