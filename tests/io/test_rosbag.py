"""ROS 1 / ROS 2 (sqlite3, mcap) bags without ROS: IMU and NavSatFix reading, stamps, topics."""

from __future__ import annotations

import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore

from imunoise.errors import DataError
from imunoise.io import rosbag as rb
from imunoise.io.imu_input import read_imu_source
from imunoise.io.tabular import TimingWarning

FORMATS = ["a.bag", "b.db3", "c.mcap"]


def _data(n=300, seed=0):
    rng = np.random.default_rng(seed)
    t = 1_700_000_000 + np.arange(n) * 0.005
    return t, rng.normal(size=(n, 3)), rng.normal(9.8, 0.1, size=(n, 3))


@pytest.mark.parametrize("name", FORMATS)
def test_write_read_roundtrip_is_exact(tmp_path, name):
    t, g, a = _data()
    path = rb.write_imu_bag(tmp_path / name, t, g, a, topic="/imu0", frame_id="imu_link")
    bag = rb.read_imu_bag(path)
    assert bag.topic == "/imu0" and bag.frame_id == "imu_link"
    np.testing.assert_array_equal(bag.gyro, g)
    np.testing.assert_array_equal(bag.accel, a)
    np.testing.assert_array_equal(bag.stamp_ns, np.round(t * 1e9).astype(np.int64))
    assert bag.report.rate_hz == pytest.approx(200.0, rel=1e-6) and bag.report.n_duplicates == 0
    frd = bag.to_imudata("FRD")
    # REP 103 FLU -> FRD (docs/guide/theory.rst, 'Conventions')
    np.testing.assert_array_equal(frd.dtheta, g * [1, -1, -1])


def _library_bag(path, ros1: bool, records):
    """A bag written only with the rosbags library (independent of imunoise's writer)."""
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    T = ts.types
    writer = Writer1(path) if ros1 else Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP)
    with writer:
        conns = {}
        for topic, typ in (
            ("/imu/a", "sensor_msgs/msg/Imu"),
            ("/imu/b", "sensor_msgs/msg/Imu"),
            ("/gps", "sensor_msgs/msg/NavSatFix"),
        ):
            conns[topic] = writer.add_connection(topic, typ, typestore=ts)
        for k, (ns, frame, w, acc) in enumerate(records):
            hdr = {"stamp": T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9), "frame_id": frame}
            if ros1:
                hdr["seq"] = k
            V3, Q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
            msg = T["sensor_msgs/msg/Imu"](
                header=T["std_msgs/msg/Header"](**hdr),
                orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0),
                orientation_covariance=np.zeros(9),
                angular_velocity=V3(x=w[0], y=w[1], z=w[2]),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=V3(x=acc[0], y=acc[1], z=acc[2]),
                linear_acceleration_covariance=np.zeros(9),
            )
            raw = ts.serialize_ros1(msg, msg.__msgtype__) if ros1 else ts.serialize_cdr(msg, msg.__msgtype__)
            writer.write(conns["/imu/a"], 1_000_000 * k, raw)  # bag time in arrival order
        writer.write(conns["/imu/b"], 0, raw)
    return path


@pytest.mark.parametrize("ros1", [True, False])
def test_library_written_bag_sorted_deduplicated_mixed_frames(tmp_path, ros1):
    rng = np.random.default_rng(1)
    n = 40
    ns = 5_000_000_000 + np.arange(n, dtype=np.int64) * 10_000_000  # 100 Hz
    order = np.arange(n)
    order[[5, 6]] = order[[6, 5]]  # arrives out of order
    recs = [(int(ns[i]), "imu" if i % 2 else "imu_link_long", rng.normal(size=3), rng.normal(size=3)) for i in order]
    recs.insert(12, recs[11])  # a duplicated message
    path = _library_bag(tmp_path / ("x.bag" if ros1 else "x"), ros1, recs)
    with pytest.raises(DataError, match="2 IMU topics") as exc:
        rb.read_imu_bag(path)
    assert "/imu/a" in str(exc.value) and "/gps" in str(exc.value)
    with pytest.raises(DataError, match="no topic '/nope'"):
        rb.read_imu_bag(path, "/nope")
    with pytest.warns(TimingWarning):
        bag = rb.read_imu_bag(path, "/imu/a")
    assert bag.report.n_unsorted == 1 and bag.report.n_duplicates == 1 and len(bag) == n
    np.testing.assert_array_equal(bag.stamp_ns, ns)
    truth = {r[0]: (r[2], r[3]) for r in recs}
    np.testing.assert_array_equal(bag.gyro, np.array([truth[int(s)][0] for s in ns]))
    np.testing.assert_array_equal(bag.accel, np.array([truth[int(s)][1] for s in ns]))
    assert bag.report.rate_hz == pytest.approx(100.0)


def test_fast_decoder_equals_generic_deserialiser(tmp_path, monkeypatch):
    t, g, a = _data(64, seed=2)
    for name in FORMATS:
        path = rb.write_imu_bag(tmp_path / name, t, g, a)
        fast = rb.read_imu_bag(path)
        with monkeypatch.context() as m:
            m.setattr(rb, "_decode_block", lambda block, ros1: None)
            slow = rb.read_imu_bag(path)
        np.testing.assert_array_equal(fast.gyro, slow.gyro)
        np.testing.assert_array_equal(fast.stamp_ns, slow.stamp_ns)
        if name.endswith(".bag"):  # the ROS 1 chunk reader is used for our bags, and agrees too
            from rosbags.highlevel import AnyReader

            with AnyReader([path]) as reader:
                ns, block = rb._ros1_blocks(reader, reader.connections)
            assert block.shape == (64, 315) and np.array_equal(ns, fast.stamp_ns)
            with monkeypatch.context() as m:
                m.setattr(rb, "_ros1_blocks", lambda reader, conns: None)
                generic = rb.read_imu_bag(path)
            np.testing.assert_array_equal(fast.accel, generic.accel)


def test_zero_header_stamps_fall_back_to_bag_time(tmp_path):
    rng = np.random.default_rng(4)
    recs = [(0, "imu", rng.normal(size=3), rng.normal(size=3)) for _ in range(30)]
    path = _library_bag(tmp_path / "z.bag", True, recs)
    with pytest.warns(TimingWarning, match="header stamp is zero"):
        bag = rb.read_imu_bag(path, "/imu/a")
    assert bag.report.rate_hz == pytest.approx(1000.0) and "receive time" in bag.report.source
    np.testing.assert_array_equal(bag.gyro, np.array([r[2] for r in recs]))


def test_navsat_and_ros2_paths(tmp_path):
    t, g, a = _data(200)
    k = 5
    cov = np.tile([4.0, 0, 0, 0, 9.0, 0, 0, 0, 16.0], (k, 1))  # ENU variances: σE 2, σN 3, σU 4
    nav = (t[0] + np.arange(k) * 0.2, np.full(k, 40.0), np.full(k, -105.0), np.full(k, 1600.0), cov)
    path = rb.write_imu_bag(tmp_path / "n.db3", t, g, a, navsat=nav)
    assert path == tmp_path / "n" / "n.db3"
    topics = {x.name: x for x in rb.list_topics(path)}
    assert topics["/fix"].count == k and topics["/imu0"].count == 200
    fix = rb.read_navsat_bag(tmp_path / "n")  # the ROS 2 folder reads the same
    np.testing.assert_allclose(fix.sigma_ned, [[3.0, 2.0, 4.0]] * k)
    np.testing.assert_allclose(np.degrees(fix.llh[:, :2]), [[40.0, -105.0]] * k)
    s = read_imu_source(tmp_path / "n", columns="gyro_z,accel_x")
    assert s.axes == ["gyro_z", "accel_x"] and s.freq == pytest.approx(200.0)
    np.testing.assert_array_equal(s.data["gyro_z"], g[:, 2])
    with pytest.raises(DataError, match="unknown IMU axis"):
        read_imu_source(path, columns="gx")
