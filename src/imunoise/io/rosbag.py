"""ROS 1 (``.bag``) and ROS 2 (``.db3``, ``.mcap`` or a bag folder) readers and writers without a ROS
install, built on the ``rosbags`` library (docs/guide/theory.rst, 'Interfaces').

- ``sensor_msgs/Imu``: ``angular_velocity`` [rad/s] and ``linear_acceleration`` [m/s²] (REP 145 units, so
  no conversion), time = header stamp (the bag receive time only when every header stamp is zero or
  when asked). Stamps are sorted, duplicates dropped and counted, gaps and jitter reported
  (:func:`imunoise.io.tabular.clean_time`).
- ``sensor_msgs/NavSatFix``: fixes with ``status >= 0``; σ from the diagonal of ``position_covariance``
  (ENU in ROS, reordered to NED), a default σ when the covariance type is unknown.

Reading millions of IMU messages through the generic deserialiser costs ~20 µs each; all messages of
one length share one layout, so they are decoded at once with NumPy from the raw bytes at the field
offsets of the ROS 1 / little-endian CDR layout. The offsets are checked against the ``rosbags``
deserialiser on the first and last message of each layout, and the generic path is used if they differ.

Body frame: ROS uses FLU (x forward, y left, z up, REP 103); imunoise navigation uses FRD
(docs/guide/theory.rst, 'Conventions').
:meth:`BagImu.to_imudata` converts (y and z negated); the per-axis noise models do not depend on the
sign, so ``imunoise fit`` models the axes as recorded.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.errors import DataError

# _decode_block and _ros1_blocks are module attributes here so that a test can switch the fast decoders off
from imunoise.io.bag_decode import decode_block as _decode_block
from imunoise.io.bag_decode import msg_values, verified
from imunoise.io.bag_decode import ros1_blocks as _ros1_blocks
from imunoise.io.bag_topics import (
    BAG_SUFFIXES,
    IMU_TYPES,
    NAVSAT_TYPES,
    BagTopic,
    choose_topic,
    imu_topic,
    is_bag,
    list_topics,
    open_bag,
    topics_of,
)
from imunoise.io.bag_write import write_imu_bag
from imunoise.io.tabular import GAP_FACTOR, TimeReport, TimingWarning, clean_time

__all__ = [
    "BAG_SUFFIXES",
    "IMU_TYPES",
    "NAVSAT_TYPES",
    "BagTopic",
    "BagImu",
    "BagNavSat",
    "BagImuBlock",
    "imu_topic",
    "iter_imu_bag",
    "is_bag",
    "list_topics",
    "read_imu_bag",
    "read_navsat_bag",
    "write_imu_bag",
]


DEFAULT_NAVSAT_SIGMA_M = (5.0, 5.0, 10.0)
"""σ (N, E, D) in m used when a NavSatFix has COVARIANCE_TYPE_UNKNOWN."""

# ----------------------------------------------------------------------------------------------
# IMU
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class BagImu:
    """IMU samples from a bag: ``t`` [s] (header stamps), ``gyro`` [rad/s] and ``accel`` [m/s²], each
    (n, 3) in the message frame (ROS FLU), time-sorted without duplicates; ``stamp_ns`` the same times as
    integer ns."""

    path: str
    topic: str
    frame_id: str
    t: np.ndarray
    stamp_ns: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray
    report: TimeReport
    extra: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.t.size)

    @property
    def rate_hz(self) -> float:
        return self.report.rate_hz

    def axes(self) -> dict[str, np.ndarray]:
        """``gyro_x`` … ``accel_z`` columns (message frame, SI)."""
        out = {}
        for sensor, arr in (("gyro", self.gyro), ("accel", self.accel)):
            for i, a in enumerate("xyz"):
                out[f"{sensor}_{a}"] = np.ascontiguousarray(arr[:, i])
        return out

    def to_imudata(self, frame: str = "FRD"):
        """:class:`imunoise.imu.ImuData` of rates; ``frame="FRD"`` negates y and z (ROS FLU -> FRD)."""
        from imunoise.imu import ImuData

        if frame not in ("FRD", "FLU"):
            raise DataError(f"frame must be 'FRD' or 'FLU', got {frame!r}")
        s = np.array([1.0, -1.0, -1.0]) if frame == "FRD" else np.ones(3)
        return ImuData(self.t, self.gyro * s, self.accel * s, kind="rates", frame=frame)



def _decode_imu(reader, raws: list[bytes], msgtype: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    n = len(raws)
    lengths = np.fromiter((len(r) for r in raws), dtype=np.int64, count=n)
    stamp = np.empty(n, dtype=np.int64)
    gyro = np.empty((n, 3))
    accel = np.empty((n, 3))
    frame_id = ""
    ros1 = not reader.is2
    for length in np.unique(lengths):
        idx = np.flatnonzero(lengths == length)
        block = np.frombuffer(b"".join(raws[i] for i in idx), dtype=np.uint8).reshape(idx.size, int(length))
        fast = _decode_block(block, ros1)
        ok = fast is not None
        if ok:
            # verify the layout against the library's deserialiser on the first and last message
            ok = verified(reader, [raws[idx[0]], raws[idx[-1]]], msgtype, fast, [0, idx.size - 1])
        if ok:
            stamp[idx], gyro[idx], accel[idx] = fast[0], fast[1], fast[2]
        else:
            for i in idx:
                stamp[i], gyro[i], accel[i] = msg_values(reader.deserialize(raws[i], msgtype))
        if not frame_id:
            frame_id = str(reader.deserialize(raws[idx[0]], msgtype).header.frame_id)
    return stamp, gyro, accel, frame_id



def read_imu_bag(
    path: str | Path,
    topic: str | None = None,
    *,
    stamps: str = "header",
    freq: float | None = None,
    gap_factor: float = GAP_FACTOR,
) -> BagImu:
    """Read a ``sensor_msgs/Imu`` topic (the only one when ``topic`` is None; otherwise the topics are
    listed in the error). ``stamps``: ``"header"`` (default; falls back to the bag time with a warning
    when all header stamps are zero) or ``"bag"`` (receive time). ``freq`` is checked against the stamps."""
    path = Path(path)
    if stamps not in ("header", "bag"):
        raise DataError(f"stamps must be 'header' or 'bag', got {stamps!r}")
    reader = open_bag(path)
    try:
        topics = topics_of(reader)
        name = choose_topic(path, topics, topic, IMU_TYPES, "IMU")
        conns = [c for c in reader.connections if c.topic == name]
        msgtype = conns[0].msgtype
        fast = _ros1_blocks(reader, conns)
        if fast is not None:
            bag_ns, block = fast
            raws = [block[0].tobytes(), block[-1].tobytes()]
            decoded = _decode_block(block, ros1=True)
            if decoded is None or not verified(reader, raws, msgtype, decoded, [0, -1]):
                fast = None
        if fast is None:
            msgs = list(reader.messages(connections=conns))
            bag_ns = [m[1] for m in msgs]
            raws = [m[2] for m in msgs]  # bytes or memoryview: both join and deserialise
            del msgs
            if len(raws) < 2:
                raise DataError(f"topic {name!r} of {path} has {len(raws)} message(s); need a recording")
            stamp, gyro, accel, frame_id = _decode_imu(reader, raws, msgtype)
        else:
            stamp, gyro, accel = decoded[0], decoded[1], decoded[2]
            frame_id = str(reader.deserialize(raws[0], msgtype).header.frame_id)
    finally:
        reader.close()
    source = f"{path}:{name} header stamps"
    if stamps == "bag" or not np.any(stamp):
        if stamps == "header":
            warnings.warn(
                f"{path}:{name}: every header stamp is zero; using the bag receive time instead",
                TimingWarning,
                stacklevel=2,
            )
        stamp = np.asarray(bag_ns, dtype=np.int64)
        source = f"{path}:{name} bag receive time"
    bad = ~(np.isfinite(gyro).all(axis=1) & np.isfinite(accel).all(axis=1))
    if bad.any():
        raise DataError(
            f"{path}:{name}: {int(bad.sum())} message(s) with NaN/Inf rates, first at message "
            f"{int(np.flatnonzero(bad)[0])}; filter the bag"
        )
    t_rel = (stamp - stamp.min()).astype(float) * 1e-9
    keep, report = clean_time(t_rel, source=source, freq=freq, gap_factor=gap_factor)
    stamp = stamp[keep]
    return BagImu(
        path=str(path),
        topic=name,
        frame_id=frame_id,
        t=stamp.astype(float) * 1e-9,
        stamp_ns=stamp,
        gyro=gyro[keep],
        accel=accel[keep],
        report=report,
        extra={"topics": [str(t) for t in topics], "stamps": source},
    )



@dataclass(frozen=True, eq=False)
class BagImuBlock:
    """Consecutive IMU messages in bag order: header and receive stamps [ns], gyro and accel (n, 3) in SI."""

    stamp_ns: np.ndarray
    bag_ns: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray
    frame_id: str


def iter_imu_bag(path: str | Path, topic: str | None = None, *, batch: int = 1 << 14) -> Iterator[BagImuBlock]:
    """The messages of an IMU topic in bag (receive-time) order, ``batch`` at a time, decoded as in
    :func:`read_imu_bag` (fast fixed-layout decoding checked against the library's deserialiser) but never
    all held at once. Nothing is sorted or cleaned here: :func:`read_imu_bag` sorts by header stamp, a
    stream cannot (``imunoise.io.imu_stream`` refuses out-of-order stamps)."""
    path = Path(path)
    reader = open_bag(path)
    try:
        name = choose_topic(path, topics_of(reader), topic, IMU_TYPES, "IMU")
        conns = [c for c in reader.connections if c.topic == name]
        msgtype = conns[0].msgtype
        bag_ns: list[int] = []
        raws: list[bytes] = []
        frame_id = ""
        for _, t_ns, raw in reader.messages(connections=conns):
            bag_ns.append(t_ns)
            raws.append(raw)
            if len(raws) == batch:
                stamp, gyro, accel, fid = _decode_imu(reader, raws, msgtype)
                frame_id = frame_id or fid
                yield BagImuBlock(stamp, np.asarray(bag_ns, dtype=np.int64), gyro, accel, frame_id)
                bag_ns, raws = [], []
        if raws:
            stamp, gyro, accel, fid = _decode_imu(reader, raws, msgtype)
            yield BagImuBlock(stamp, np.asarray(bag_ns, dtype=np.int64), gyro, accel, frame_id or fid)
    finally:
        reader.close()


# ----------------------------------------------------------------------------------------------
# NavSatFix
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class BagNavSat:
    """GNSS fixes: ``t`` [s], ``llh`` [lat rad, lon rad, h m], ``sigma_ned`` [m]; ``n_no_fix`` fixes with
    status −1 dropped, ``n_default_sigma`` fixes whose covariance was unknown (default σ used); ``stamp_ns``
    the same times as integer ns (exact, for changing the time base)."""

    path: str
    topic: str
    t: np.ndarray
    llh: np.ndarray
    sigma_ned: np.ndarray
    report: TimeReport
    n_no_fix: int
    n_default_sigma: int
    stamp_ns: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def to_gnssdata(self):
        from imunoise.io.kfgins import GnssData

        return GnssData(self.t, self.llh, self.sigma_ned)


def read_navsat_bag(
    path: str | Path,
    topic: str | None = None,
    *,
    default_sigma_m: tuple[float, float, float] = DEFAULT_NAVSAT_SIGMA_M,
) -> BagNavSat:
    """Read a ``sensor_msgs/NavSatFix`` topic; fixes without a fix (status −1) are dropped and counted."""
    path = Path(path)
    reader = open_bag(path)
    try:
        topics = topics_of(reader)
        name = choose_topic(path, topics, topic, NAVSAT_TYPES, "NavSatFix")
        conns = [c for c in reader.connections if c.topic == name]
        rows = []
        for conn, _, raw in reader.messages(connections=conns):
            m = reader.deserialize(raw, conn.msgtype)
            st = m.header.stamp
            ns = int(st.sec) * 1_000_000_000 + int(getattr(st, "nanosec", getattr(st, "nsec", 0)))
            cov = np.asarray(m.position_covariance, dtype=float)
            rows.append(
                (ns, int(m.status.status), m.latitude, m.longitude, m.altitude, int(m.position_covariance_type), cov)
            )
    finally:
        reader.close()
    fix = [r for r in rows if r[1] >= 0]
    n_no_fix = len(rows) - len(fix)
    if len(fix) < 2:
        raise DataError(f"topic {name!r} of {path} has {len(fix)} valid fix(es) ({n_no_fix} without a fix)")
    stamp = np.array([r[0] for r in fix], dtype=np.int64)
    llh = np.array([[np.radians(r[2]), np.radians(r[3]), r[4]] for r in fix])
    sigma = np.empty((len(fix), 3))
    n_default = 0
    for i, r in enumerate(fix):
        if r[5] == 0 or not np.all(np.isfinite(r[6][[0, 4, 8]])) or np.any(r[6][[0, 4, 8]] <= 0):
            sigma[i] = default_sigma_m
            n_default += 1
        else:
            east, north, up = np.sqrt(r[6][[0, 4, 8]])  # ROS: ENU covariance
            sigma[i] = (north, east, up)
    if n_no_fix:
        warnings.warn(f"{path}:{name}: dropped {n_no_fix} messages without a fix (status −1)", TimingWarning, 2)
    if n_default:
        warnings.warn(
            f"{path}:{name}: {n_default} fixes without a covariance; σ NED = {default_sigma_m} m used",
            TimingWarning,
            2,
        )
    t_rel = (stamp - stamp.min()).astype(float) * 1e-9
    keep, report = clean_time(t_rel, source=f"{path}:{name} header stamps")
    return BagNavSat(
        path=str(path),
        topic=name,
        t=stamp[keep].astype(float) * 1e-9,
        llh=llh[keep],
        sigma_ned=sigma[keep],
        report=report,
        n_no_fix=n_no_fix,
        n_default_sigma=n_default,
        stamp_ns=stamp[keep],
    )
