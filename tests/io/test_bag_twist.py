"""Twist topics of a bag (imunoise.io.bag_twist) written by the repository's bag writer and read back: GNSS velocity
(ENU TwistWithCovarianceStamped / TwistStamped → NED, σ from the covariance) in ROS 1 and ROS 2 bags."""

from __future__ import annotations

import numpy as np
import pytest

from imunoise.errors import DataError
from imunoise.io.bag_twist import read_twist_topic
from imunoise.io.bag_write import write_imu_bag
from imunoise.io.gnss_velocity import read_gnss_velocity

pytest.importorskip("rosbags")


def _bag(path, twists):
    t = 100.0 + np.arange(400) * 0.01
    return write_imu_bag(path, t, np.zeros((t.size, 3)), np.tile([0.0, 0.0, 9.8], (t.size, 1)), twists=twists), t


@pytest.mark.parametrize("name", ["drive.bag", "drive.db3"])
def test_gnss_velocity_round_trips_through_a_bag(tmp_path, name):
    tv = 100.5 + np.arange(12) * 0.25
    enu = np.column_stack([np.linspace(1, 2, 12), np.linspace(-3, 3, 12), np.full(12, 0.1)])
    var = np.tile([0.04**2, 0.03**2, 0.05**2], (12, 1))
    bag, t = _bag(tmp_path / name, {"/fix_velocity": (tv, enu, var), "/odom_speed": (tv, enu)})
    v = read_gnss_velocity(bag, imu_t=t, topic="/fix_velocity")
    assert np.allclose(v.t, tv, atol=1e-9)
    assert np.allclose(v.vel_ned, enu[:, [1, 0, 2]] * [1, 1, -1])  # ENU → NED
    assert np.allclose(v.sigma_ned, np.tile([0.03, 0.04, 0.05], (12, 1)))
    w = read_gnss_velocity(bag, imu_t=t, topic="/odom_speed", sigma=0.2)  # TwistStamped: no covariance
    assert np.allclose(w.sigma_ned, 0.2) and np.allclose(w.vel_ned, v.vel_ned)
    tw = read_twist_topic(bag, "/odom_speed", "--gnss-vel")
    assert tw.msgtype.endswith("TwistStamped") and np.all(np.isnan(tw.var))


def test_two_twist_topics_need_a_choice(tmp_path):
    tv = 100.5 + np.arange(4) * 0.25
    bag, t = _bag(tmp_path / "two.bag", {"/a": (tv, np.ones((4, 3))), "/b": (tv, np.ones((4, 3)))})
    with pytest.raises(DataError, match="choose one with --gnss-vel-topic"):
        read_gnss_velocity(bag, imu_t=t)
    with pytest.raises(DataError, match="no topic '/c'"):
        read_gnss_velocity(bag, imu_t=t, topic="/c")
