"""The mounting check and rotation (imunoise.nav.mounting): exact rotation identities, the angles recovered from
simulated drives with the IMU turned in its mount, and the one-line warning with the --mount-rpy that fixes it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imunoise.errors import ModelError
from imunoise.nav.earth import euler_to_dcm, llh_to_ned
from imunoise.nav.mounting import (
    estimate_mounting,
    mount_matrix,
    mounting_warning,
    parse_mount_rpy,
    rotate_imu,
    sideslip_deg,
)
from imunoise.sim.drive import DriveConfig, simulate_drive


@pytest.fixture(scope="module")
def drive():
    """300 s simulated drive, SPP-like 1 m GNSS, grades up to 3° and body roll in turns (the simulator's)."""
    return simulate_drive(DriveConfig(duration_s=300.0, n_stops=2, static_s=40.0, seed=4210), "mems", seed=4210)


def check(d, rpy, given=None):
    """The estimate and warning for the drive's IMU mounted at ``rpy`` (then turned back by ``given``)."""
    imu = rotate_imu(d.imu, mount_matrix(rpy).T)  # x_imu = C_s^vᵀ x_vehicle
    if given is not None:
        imu = rotate_imu(imu, mount_matrix(given))
    g = d.gnss
    sig = float(np.median(np.hypot(g.sigma_ned[:, 0], g.sigma_ned[:, 1])))
    est = estimate_mounting(imu.t, imu.dv, imu.t <= imu.t[0] + 30.0, g.t, llh_to_ned(g.llh, g.llh[0]), sig)
    return est, mounting_warning(est, "imu.txt", given=given)


def test_the_mounting_matrix_is_an_attitude_and_the_rotation_exact(drive):
    assert mount_matrix((0, 0, 90)) @ [1.0, 0.0, 0.0] == pytest.approx([0.0, 1.0, 0.0], abs=1e-15)  # x → right
    C = mount_matrix((12.0, -7.0, 133.0))
    assert C.T @ C == pytest.approx(np.eye(3), abs=1e-15)
    back = rotate_imu(rotate_imu(drive.imu, C.T), C)
    assert np.max(np.abs(back.dtheta - drive.imu.dtheta)) < 1e-17
    assert np.max(np.abs(back.dv - drive.imu.dv)) < 1e-15


def test_an_imu_mounted_straight_raises_no_warning(drive):
    est, note = check(drive, (0.0, 0.0, 0.0))
    # the sweep over 50 development drives (docs/evidence/imu_mounting.md): |yaw| ≤ 2.5°, tilt ≤ 0.8°
    assert note is None and abs(est.yaw_deg) < 5.0 and max(abs(est.roll_deg), abs(est.pitch_deg)) < 2.0
    assert est.epochs > 50 and est.half_window_s == pytest.approx(4.0)  # 1 m σ: ±4 s keeps 0.2 m/s²


@pytest.mark.parametrize(("rpy", "fix"), [((0.0, 0.0, 90.0), "0,0,90"), ((0.0, 0.0, -135.0), "0,0,-135"),
                                          ((30.0, 0.0, 0.0), "30,0,0"), ((0.0, -20.0, 0.0), "0,-20,0")])
def test_a_turned_or_tilted_imu_is_said_in_one_line_with_the_fix(drive, rpy, fix):
    est, note = check(drive, rpy)
    assert est.roll_deg == pytest.approx(rpy[0], abs=2.0) and est.pitch_deg == pytest.approx(rpy[1], abs=2.0)
    assert (est.yaw_deg - rpy[2] + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=5.0)
    assert note is not None and "\n" not in note and note.startswith("IMU imu.txt looks mounted")
    given = note.rsplit("give --mount-rpy ", 1)[1]
    if fix == "0,0,-135":  # not a right angle: the estimate, to the degree
        assert given.startswith("0,0,") and float(given.split(",")[2]) == pytest.approx(-135.0, abs=5.0)
    else:  # a right angle, or a tilt (to the degree, within 2°)
        assert np.allclose([float(x) for x in given.split(",")], [float(x) for x in fix.split(",")], atol=2.0)


def test_the_fix_adds_to_the_mounting_already_given(drive):
    _, note = check(drive, (0.0, 0.0, 90.0), given=(0.0, 0.0, 45.0))  # half-corrected: 45° left
    assert "in yaw" in note and note.endswith("give --mount-rpy 0,0,90")
    est, note = check(drive, (0.0, 0.0, 90.0), given=(0.0, 0.0, 90.0))
    assert note is None and abs(est.yaw_deg) < 5.0


def test_mount_rpy_is_three_finite_angles():
    assert parse_mount_rpy("0, 0,90") == (0.0, 0.0, 90.0)
    for bad in ("90", "0,0", "0,0,x", "0,0,nan"):
        with pytest.raises(ModelError, match="--mount-rpy takes roll,pitch,yaw in degrees"):
            parse_mount_rpy(bad)


def test_the_sideslip_is_minus_the_yaw_of_the_mounting():
    n = 50
    yaw = math.radians(90.0)  # the filter's IMU heading east, the vehicle going north: x points right
    euler = np.tile([0.0, 0.0, yaw], (n, 1))
    vel = np.tile([10.0, 0.0, 0.0], (n, 1))
    assert sideslip_deg(euler, vel) == pytest.approx(-90.0, abs=1e-9)
    C = np.asarray(euler_to_dcm(0.0, 0.0, 0.3))
    assert sideslip_deg(np.tile([0.0, 0.0, 0.3], (n, 1)), np.tile(C @ [5.0, 0.0, 0.0], (n, 1))) == pytest.approx(0.0)
    assert sideslip_deg(euler, 0.1 * vel) is None  # never faster than 3 m/s
