"""Writing ``sensor_msgs/Imu`` (and optionally ``sensor_msgs/NavSatFix``) messages to a ROS 1 or ROS 2 bag
(simulations, tests, converting CSV logs to bags; docs/guide/theory.rst, 'Interfaces')."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.errors import DataError
from imunoise.io.bag_decode import cdr_offsets, ros1_offsets
from imunoise.io.bag_twist import twist_messages

__all__ = ["write_imu_bag"]


def _imu_records(stamp_ns: np.ndarray, gyro: np.ndarray, accel: np.ndarray, frame_id: str, ros1: bool) -> np.ndarray:
    """Serialised sensor_msgs/Imu messages (n, size) for the fixed layout of
    :func:`imunoise.io.bag_decode.decode_block`."""
    fid = frame_id.encode()
    n = stamp_ns.size
    sec = stamp_ns // 1_000_000_000
    nsec = stamp_ns - sec * 1_000_000_000
    if ros1:
        off = ros1_offsets(len(fid))
        rec = np.zeros((n, off["size"]), dtype=np.uint8)
        rec[:, 0:4] = np.arange(n, dtype="<u4").view(np.uint8).reshape(n, 4)  # seq
        rec[:, 12:16] = np.frombuffer(np.uint32(len(fid)).astype("<u4").tobytes(), np.uint8)
        rec[:, 16 : 16 + len(fid)] = np.frombuffer(fid, np.uint8)
        sec_t = "<u4"
        q = 16 + len(fid)
    else:
        off = cdr_offsets(len(fid) + 1)
        rec = np.zeros((n, off["size"]), dtype=np.uint8)
        rec[:, 0:4] = np.frombuffer(b"\x00\x01\x00\x00", np.uint8)
        rec[:, 12:16] = np.frombuffer(np.uint32(len(fid) + 1).astype("<u4").tobytes(), np.uint8)
        rec[:, 16 : 16 + len(fid)] = np.frombuffer(fid, np.uint8)
        sec_t = "<i4"
        q = off["av"] - 104
    rec[:, off["sec"] : off["sec"] + 4] = sec.astype(sec_t).view(np.uint8).reshape(n, 4)
    rec[:, off["nsec"] : off["nsec"] + 4] = nsec.astype("<u4").view(np.uint8).reshape(n, 4)
    rec[:, q + 24 : q + 32] = np.frombuffer(np.float64(1.0).astype("<f8").tobytes(), np.uint8)  # w = 1
    # orientation unknown: orientation_covariance[0] = −1 (REP 145 convention)
    rec[:, q + 32 : q + 40] = np.frombuffer(np.float64(-1.0).astype("<f8").tobytes(), np.uint8)
    rec[:, off["av"] : off["av"] + 24] = np.ascontiguousarray(gyro, dtype="<f8").view(np.uint8).reshape(n, 24)
    rec[:, off["la"] : off["la"] + 24] = np.ascontiguousarray(accel, dtype="<f8").view(np.uint8).reshape(n, 24)
    return rec


def _navsat_messages(typestore, navsat: Any, ros1: bool) -> Iterable[tuple[int, bytes]]:
    t = np.asarray(navsat[0])
    # integer stamps are ns (exact), as for the IMU
    stamps = t.astype(np.int64) if np.issubdtype(t.dtype, np.integer) else np.round(t * 1e9).astype(np.int64)
    lat, lon, alt = (np.asarray(a, dtype=float) for a in navsat[1:4])
    cov = np.asarray(navsat[4], dtype=float) if len(navsat) > 4 and navsat[4] is not None else None
    status = np.asarray(navsat[5], dtype=int) if len(navsat) > 5 and navsat[5] is not None else None
    T = typestore.types
    for i in range(stamps.size):
        ns = int(stamps[i])
        stamp = T["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        hdr = {"stamp": stamp, "frame_id": "gps"}
        if ros1:
            hdr["seq"] = i
        c = np.zeros(9) if cov is None else cov[i]
        msg = T["sensor_msgs/msg/NavSatFix"](
            header=T["std_msgs/msg/Header"](**hdr),
            status=T["sensor_msgs/msg/NavSatStatus"](status=0 if status is None else int(status[i]), service=1),
            latitude=float(lat[i]),
            longitude=float(lon[i]),
            altitude=float(alt[i]),
            position_covariance=c,
            position_covariance_type=0 if cov is None else 2,
        )
        raw = (
            typestore.serialize_ros1(msg, "sensor_msgs/msg/NavSatFix")
            if ros1
            else typestore.serialize_cdr(msg, "sensor_msgs/msg/NavSatFix")
        )
        yield ns, bytes(raw)


def write_imu_bag(
    path: str | Path,
    t: np.ndarray,
    gyro: np.ndarray,
    accel: np.ndarray,
    *,
    topic: str = "/imu0",
    frame_id: str = "imu",
    navsat: tuple | None = None,
    navsat_topic: str = "/fix",
    twists: dict[str, tuple] | None = None,
) -> Path:
    """Write ``sensor_msgs/Imu`` messages (``t`` s as float, or integer ns; ``gyro`` rad/s, ``accel`` m/s²,
    (n, 3)) to a bag whose format follows the suffix: ``.bag`` ROS 1 (Noetic types); ``.db3`` / ``.mcap``
    a ROS 2 (Humble) bag folder ``<stem>/`` holding ``<stem>.db3`` / ``<stem>.mcap`` and metadata.yaml —
    the storage file's path is returned; any other name: a ROS 2 sqlite3 bag folder. Header stamp = bag time = ``t``.
    ``navsat`` = (t, lat_deg, lon_deg, alt_m[, cov (n, 9) ENU m²[, status (n,)]]) adds a NavSatFix topic
    (``t`` s or integer ns; status 0 = fix, −1 = no fix). ``twists`` = {topic: (t, linear (n, 3) m/s[, variance
    (n, 3)])} adds twist topics (:func:`imunoise.io.bag_twist.twist_messages`: a GNSS velocity, a wheel speed)."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    t = np.asarray(t)
    # integer stamps are ns (exact); float seconds near the Unix epoch carry ~0.2 µs rounding
    stamp = t.astype(np.int64) if np.issubdtype(t.dtype, np.integer) else np.round(t * 1e9).astype(np.int64)
    gyro = np.asarray(gyro, dtype=float).reshape(-1, 3)
    accel = np.asarray(accel, dtype=float).reshape(-1, 3)
    if not (t.ndim == 1 and gyro.shape[0] == t.size == accel.shape[0]):
        raise DataError(f"t {t.shape}, gyro {gyro.shape} and accel {accel.shape} must have the same length")
    ros1 = path.suffix == ".bag"
    target = path if ros1 or path.suffix not in (".db3", ".mcap") else path.with_suffix("")
    if target.exists():
        raise DataError(f"{target} exists already; bags are never overwritten — remove it or choose another name")
    rec = _imu_records(stamp, gyro, accel, frame_id, ros1)
    if ros1:
        typestore = get_typestore(Stores.ROS1_NOETIC)
        writer = Writer1(path)
        result = path
    else:
        typestore = get_typestore(Stores.ROS2_HUMBLE)
        plugin = StoragePlugin.MCAP if path.suffix == ".mcap" else StoragePlugin.SQLITE3
        folder = path.with_suffix("") if path.suffix in (".db3", ".mcap") else path
        writer = Writer2(folder, version=9, storage_plugin=plugin)
        ext = ".mcap" if plugin == StoragePlugin.MCAP else ".db3"
        result = folder / f"{folder.name}{ext}" if path.suffix in (".db3", ".mcap") else folder
    with writer:
        conn = writer.add_connection(topic, "sensor_msgs/msg/Imu", typestore=typestore)
        if navsat is None and not twists:
            for ns, row in zip(stamp.tolist(), rec):
                writer.write(conn, ns, row.tobytes())
            return result
        conns = [conn]
        events: list[tuple[int, int, Any]] = [(ns, 0, i) for i, ns in enumerate(stamp.tolist())]
        if navsat is not None:
            conns.append(writer.add_connection(navsat_topic, "sensor_msgs/msg/NavSatFix", typestore=typestore))
            events += [(ns, 1, raw) for ns, raw in _navsat_messages(typestore, navsat, ros1)]
        for name, tw in (twists or {}).items():
            msgs = list(twist_messages(typestore, tw[0], tw[1], tw[2] if len(tw) > 2 else None, ros1))
            if msgs:
                conns.append(writer.add_connection(name, msgs[0][2], typestore=typestore))
                events += [(ns, len(conns) - 1, raw) for ns, raw, _ in msgs]
        events.sort(key=lambda e: (e[0], e[1]))
        for ns, kind, item in events:
            writer.write(conn, ns, rec[item].tobytes()) if kind == 0 else writer.write(conns[kind], ns, item)
    return result
