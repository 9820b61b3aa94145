"""An IMU turned in its mount (imunoise.nav.mounting): `nav` and `online` say it in one line with the angle and
the --mount-rpy that corrects it (kept in metrics.json), and with that option the run is the straight-mounted
run's. Simulated drives (RTK-like 2 cm fixes) and the real drive data/drive_0708 with its IMU rotated."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from imunoise.cli import main
from imunoise.nav.mounting import mount_matrix

REPO = Path(__file__).resolve().parents[2]
DRIVE = REPO / "data" / "drive_0708"


def mounted(src: Path, dest: Path, rpy, imu_name: str = "imu.txt") -> Path:
    """A copy of the dataset folder ``src`` whose IMU is mounted at ``rpy`` (x_imu = C_s^vᵀ x_vehicle)."""
    shutil.copytree(src, dest)
    from imunoise.io.kfgins import read_imu

    imu = read_imu(src / imu_name)
    C = mount_matrix(rpy)
    np.savetxt(dest / imu_name, np.column_stack([imu.t, imu.dtheta @ C, imu.dv @ C]), fmt="%.17g")
    return dest


@pytest.fixture(scope="module")
def drives(tmp_path_factory) -> dict[str, Path]:
    from imunoise.sim.drive import DriveConfig, simulate_drive

    d = tmp_path_factory.mktemp("mount")
    cfg = DriveConfig(duration_s=300.0, n_stops=2, static_s=40.0, gnss_sigma_m=(0.02, 0.02, 0.05), seed=4211)
    simulate_drive(cfg, "mems", seed=4211).write(d / "straight")
    return {"straight": d / "straight", "yaw90": mounted(d / "straight", d / "yaw90", (0.0, 0.0, 90.0)),
            "roll30": mounted(d / "straight", d / "roll30", (30.0, 0.0, 0.0)), "root": d}


def run(cmd: str, data: Path, out: Path, caplog, *extra) -> tuple[dict, list[str]]:
    """The metrics of the run and its mounting warnings as logged (stderr on the command line)."""
    args = [cmd, "--data", str(data), *(["--no-plots"] if cmd == "nav" else []), *map(str, extra), "--out", str(out)]
    caplog.clear()
    assert main(args) == 0
    err = [r.getMessage() for r in caplog.records if "looks mounted" in r.getMessage()]
    return json.loads((out / "metrics.json").read_text()), err


def test_nav_says_a_yawed_imu_and_mount_rpy_gives_the_straight_run(drives, caplog):
    out = drives["root"]
    straight, none = run("nav", drives["straight"], out / "n0", caplog, "--nhc")
    assert none == [] and not any("mounted" in w for w in straight["warnings"])
    assert abs(straight["mounting"]["check"]["yaw_deg"]) < 5.0 and straight["mounting"]["mount_rpy_deg"] is None
    yawed, err = run("nav", drives["yaw90"], out / "n1", caplog, "--nhc")
    assert len(err) == 1 and err[0].endswith("give --mount-rpy 0,0,90")
    assert yawed["mounting"]["check"]["yaw_deg"] == pytest.approx(90.0, abs=5.0)
    assert [w for w in yawed["warnings"] if "looks mounted" in w] == err
    fixed, err = run("nav", drives["yaw90"], out / "n2", caplog, "--nhc", "--mount-rpy", "0,0,90")
    assert err == [] and fixed["mounting"]["mount_rpy_deg"] == [0.0, 0.0, 90.0]
    # measured: 10.8 m turned, 0.031 m straight and corrected (the same run up to the rotation's rounding)
    assert yawed["horizontal_rms_m"] > 30.0 * straight["horizontal_rms_m"]
    assert fixed["horizontal_rms_m"] == pytest.approx(straight["horizontal_rms_m"], rel=0.02)
    assert abs(fixed["mounting"]["filter_sideslip_deg"]) < 2.0  # the NHC residual's direction: x forward again


def test_nav_says_a_rolled_imu(drives, caplog):
    out = drives["root"]
    rolled, err = run("nav", drives["roll30"], out / "r1", caplog, "--nhc")
    assert len(err) == 1 and "tilted roll 30°" in err[0] and err[0].endswith("give --mount-rpy 30,0,0")
    fixed, err = run("nav", drives["roll30"], out / "r2", caplog, "--nhc", "--mount-rpy", "30,0,0")
    assert err == [] and abs(fixed["mounting"]["check"]["roll_deg"]) < 2.0
    # a roll about x keeps x forward: the run was right already, its attitude was the IMU's (now the vehicle's)
    assert fixed["horizontal_rms_m"] == pytest.approx(rolled["horizontal_rms_m"], rel=0.2)


def test_online_says_it_too_and_takes_the_option(drives, caplog):
    out = drives["root"]
    yawed, err = run("online", drives["yaw90"], out / "o1", caplog)
    assert len(err) == 1 and err[0].endswith("give --mount-rpy 0,0,90") and "mounting" in yawed
    fixed, err = run("online", drives["yaw90"], out / "o2", caplog, "--mount-rpy", "0,0,90")
    assert err == [] and abs(fixed["mounting"]["check"]["yaw_deg"]) < 5.0
    assert fixed["horizontal_rms_m"] < yawed["horizontal_rms_m"]


def test_the_warning_is_one_line_on_stderr(drives, tmp_path):
    r = subprocess.run([sys.executable, "-m", "imunoise", "nav", "--data", str(drives["yaw90"]), "--no-plots",
                        "--out", str(tmp_path / "o")], capture_output=True, text=True, timeout=600,
                       env={**os.environ, "PYTHONPATH": str(REPO / "src")})
    assert r.returncode == 0, r.stderr
    (line,) = [ln for ln in r.stderr.splitlines() if "looks mounted" in ln]
    assert line.startswith("WARNING imunoise.nav: IMU ") and line.endswith("give --mount-rpy 0,0,90")


@pytest.mark.parametrize("bad", ["90", "0,0,north"])
def test_a_malformed_mount_rpy_is_one_line(bad, drives, capsys):
    code = main(["nav", "--data", str(drives["straight"]), "--mount-rpy", bad, "--out", str(drives["root"] / "b")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--mount-rpy takes roll,pitch,yaw in degrees" in err[0]


@pytest.mark.slow
def test_the_real_drive_with_its_imu_turned_90_degrees(tmp_path, caplog):
    """data/drive_0708 (RTK 4 Hz) as recorded and with its IMU turned 90° in yaw, --nhc. Measured: check yaw 0.37°
    and 90.37°; horizontal RMS 0.026 m as recorded and corrected, 0.261 m turned."""
    turned = mounted(DRIVE, tmp_path / "turned", (0.0, 0.0, 90.0), "imu_body_inc.txt.gz")
    straight, none = run("nav", DRIVE, tmp_path / "a", caplog, "--nhc")
    yawed, err = run("nav", turned, tmp_path / "b", caplog, "--nhc")
    fixed, again = run("nav", turned, tmp_path / "c", caplog, "--nhc", "--mount-rpy", "0,0,90")
    assert none == [] and again == [] and len(err) == 1 and err[0].endswith("give --mount-rpy 0,0,90")
    assert abs(straight["mounting"]["check"]["yaw_deg"]) < 2.0
    assert yawed["mounting"]["check"]["yaw_deg"] == pytest.approx(90.0, abs=2.0)
    assert yawed["horizontal_rms_m"] > 5.0 * straight["horizontal_rms_m"]
    assert fixed["horizontal_rms_m"] == pytest.approx(straight["horizontal_rms_m"], rel=0.02)
