"""ROS 1 (``.bag``) and ROS 2 (``.db3``, ``.mcap`` or a bag folder) readers and writers without a ROS
install, built on the ``rosbags`` library (SPEC §12).

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

Body frame: ROS uses FLU (x forward, y left, z up, REP 103); imunoise navigation uses FRD (SPEC §1).
:meth:`BagImu.to_imudata` converts (y and z negated); the per-axis noise models do not depend on the
sign, so ``imunoise fit`` models the axes as recorded.
"""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.errors import DataError
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

BAG_SUFFIXES = (".bag", ".db3", ".mcap")
IMU_TYPES = ("sensor_msgs/msg/Imu", "sensor_msgs/Imu")
NAVSAT_TYPES = ("sensor_msgs/msg/NavSatFix", "sensor_msgs/NavSatFix")
DEFAULT_NAVSAT_SIGMA_M = (5.0, 5.0, 10.0)
"""σ (N, E, D) in m used when a NavSatFix has COVARIANCE_TYPE_UNKNOWN."""


def is_bag(path: str | Path) -> bool:
    """True for a ROS 1 ``.bag``, a ROS 2 ``.db3``/``.mcap`` file, or a ROS 2 folder with metadata.yaml."""
    p = Path(path)
    return p.suffix in BAG_SUFFIXES or (p.is_dir() and (p / "metadata.yaml").exists())


@dataclass(frozen=True)
class BagTopic:
    name: str
    msgtype: str
    count: int

    def __str__(self) -> str:
        return f"{self.name} [{self.msgtype}, {self.count} messages]"


def _reader(path: Path):
    from rosbags.highlevel import AnyReader

    if not path.exists():
        raise FileNotFoundError(2, "No such file", str(path))
    if not is_bag(path):
        raise DataError(f"{path} is not a ROS bag (.bag, .db3, .mcap or a ROS 2 bag folder)")
    return AnyReader([path])


def _open(path: Path):
    from rosbags.highlevel import AnyReaderError

    reader = _reader(path)
    try:
        reader.open()
    except (AnyReaderError, Exception) as exc:  # rosbags raises several unrelated types on bad files
        if isinstance(exc, FileNotFoundError):
            raise
        raise DataError(f"cannot read ROS bag {path}: {exc}") from exc
    return reader


def _topics(reader) -> list[BagTopic]:
    counts: dict[tuple[str, str], int] = {}
    for c in reader.connections:
        key = (c.topic, c.msgtype)
        counts[key] = counts.get(key, 0) + max(int(c.msgcount), 0)
    return [BagTopic(t, m, n) for (t, m), n in sorted(counts.items())]


def list_topics(path: str | Path) -> list[BagTopic]:
    """Topics of a bag with their message type and count."""
    reader = _open(Path(path))
    try:
        return _topics(reader)
    finally:
        reader.close()


def _choose_topic(path: Path, topics: list[BagTopic], topic: str | None, types: tuple[str, ...], what: str) -> str:
    listing = "\n  ".join(str(t) for t in topics) or "(none)"
    matching = [t for t in topics if t.msgtype in types]
    if topic is None:
        if len(matching) == 1:
            return matching[0].name
        if not matching:
            raise DataError(f"{path} has no {what} topic ({types[0]}); its topics are:\n  {listing}")
        raise DataError(f"{path} has {len(matching)} {what} topics; choose one with --topic. Topics:\n  {listing}")
    names = {t.name: t for t in topics}
    if topic not in names:
        raise DataError(f"{path} has no topic {topic!r}; its topics are:\n  {listing}")
    if names[topic].msgtype not in types:
        raise DataError(
            f"topic {topic!r} of {path} carries {names[topic].msgtype}, not {types[0]}; topics:\n  {listing}"
        )
    return topic


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


def _ros1_offsets(frame_len: int) -> dict[str, int]:
    # seq u32, sec u32, nsec u32, frame_id (u32 length + bytes), then packed float64 (no alignment)
    q = 16 + frame_len
    av = q + 32 + 72
    return {"sec": 4, "nsec": 8, "av": av, "la": av + 24 + 72, "size": av + 24 + 72 + 24 + 72}


def _cdr_offsets(frame_len_with_nul: int) -> dict[str, int]:
    # 4-byte encapsulation header; then sec i32, nanosec u32, frame_id (u32 length incl. NUL + bytes),
    # float64s aligned to 8 relative to the end of the encapsulation header
    p = 12 + frame_len_with_nul
    q = 4 + ((p + 7) // 8) * 8
    av = q + 32 + 72
    return {"sec": 4 + 0, "nsec": 4 + 4, "av": av, "la": av + 24 + 72, "size": av + 24 + 72 + 24 + 72}


def _f8(block: np.ndarray, off: int, k: int) -> np.ndarray:
    return np.ascontiguousarray(block[:, off : off + 8 * k]).view("<f8").reshape(-1, k)


def _decode_block(block: np.ndarray, ros1: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, int] | None:
    """(stamp_ns, gyro, accel, frame_len) for messages of one length, or None if the layout is not ours."""
    n, length = block.shape
    if ros1:
        flen = int(block[0, 12:16].view("<u4")[0])
        off = _ros1_offsets(flen)
    else:
        if block[0, 1] != 1:  # big-endian CDR: leave it to the generic deserialiser
            return None
        flen = int(block[0, 12:16].view("<u4")[0])
        off = _cdr_offsets(flen)
    if off["size"] != length:
        return None
    sec = np.ascontiguousarray(block[:, off["sec"] : off["sec"] + 4]).view("<u4" if ros1 else "<i4")
    nsec = np.ascontiguousarray(block[:, off["nsec"] : off["nsec"] + 4]).view("<u4")
    stamp = sec.astype(np.int64).ravel() * 1_000_000_000 + nsec.astype(np.int64).ravel()
    return stamp, _f8(block, off["av"], 3), _f8(block, off["la"], 3), flen


def _msg_values(msg) -> tuple[int, np.ndarray, np.ndarray]:
    st = msg.header.stamp
    ns = int(st.sec) * 1_000_000_000 + int(getattr(st, "nanosec", getattr(st, "nsec", 0)))
    w, a = msg.angular_velocity, msg.linear_acceleration
    return ns, np.array([w.x, w.y, w.z]), np.array([a.x, a.y, a.z])


def _ros1_header_fields(header: bytes) -> dict[str, tuple[int, int]]:
    """name -> (value offset, value length) inside a ROS 1 record header (u32-length-prefixed name=value)."""
    out = {}
    pos = 0
    while pos + 4 <= len(header):
        n = int.from_bytes(header[pos : pos + 4], "little")
        field = header[pos + 4 : pos + 4 + n]
        eq = field.index(b"=")
        out[field[:eq].decode()] = (pos + 4 + eq + 1, n - eq - 1)
        pos += 4 + n
    return out


def _ros1_blocks(reader, conns) -> tuple[np.ndarray, np.ndarray] | None:
    """(bag time ns, messages (n, L) uint8) of a ROS 1 bag read chunk by chunk, or None to use the generic
    reader. The per-message Python loop of the generic reader costs ~10 µs a message; here each chunk is
    decompressed once and its records (fixed header and data length) are sliced with NumPy. Every record
    is checked: op = message data, its connection is one of ``conns``, its time equals the index time."""
    try:
        if reader.is2 or len(reader.readers) != 1:
            return None
        r1 = reader.readers[0]
        ids = np.array(sorted({int(c.id) for c in conns}))
        entries = [r1.indexes[int(i)] for i in ids]
        n = sum(len(e) for e in entries)
        if n < 2:
            return None
        flat = itertools.chain.from_iterable(itertools.chain.from_iterable(entries))
        idx = np.fromiter(flat, dtype=np.int64, count=3 * n).reshape(n, 3)  # time, chunk_pos, offset
        idx = idx[np.lexsort((idx[:, 2], idx[:, 1]))]  # file order: by chunk, then offset
        starts = np.flatnonzero(np.diff(idx[:, 1])) + 1
        blocks = []
        length = None
        four = np.arange(4)
        for rows in np.split(idx, starts):
            chunk = r1.chunks[int(rows[0, 1])]
            r1.bio.seek(chunk.datapos)
            arr = np.frombuffer(chunk.decompressor(r1.bio.read(chunk.datasize)), dtype=np.uint8)
            offs = rows[:, 2]
            hlen = arr[offs[:, None] + four].copy().view("<u4").ravel()
            if np.any(hlen != hlen[0]):
                return None
            h0 = int(hlen[0])
            fields = _ros1_header_fields(arr[offs[0] + 4 : offs[0] + 4 + h0].tobytes())
            if not {"op", "conn", "time"} <= set(fields):
                return None
            base = offs + 4
            if np.any(arr[base + fields["op"][0]] != 2):  # 0x02 = message data record
                return None
            conn = arr[(base + fields["conn"][0])[:, None] + four].copy().view("<u4").ravel()
            t = arr[(base + fields["time"][0])[:, None] + np.arange(8)].copy().view("<u4").reshape(-1, 2)
            t_ns = t[:, 0].astype(np.int64) * 1_000_000_000 + t[:, 1].astype(np.int64)
            if not (np.all(np.isin(conn, ids)) and np.array_equal(t_ns, rows[:, 0])):
                return None
            dpos = base + h0
            dlen = arr[dpos[:, None] + four].copy().view("<u4").ravel()
            if np.any(dlen != dlen[0]) or (length is not None and int(dlen[0]) != length):
                return None
            length = int(dlen[0])
            stride = 4 + h0 + 4 + length
            if int(dpos[-1]) + 4 + length > arr.size:  # truncated chunk
                return None
            if offs.size > 1 and np.all(np.diff(offs) == stride):  # back-to-back records: a strided view
                view = np.lib.stride_tricks.as_strided(
                    arr[int(dpos[0]) + 4 :], shape=(offs.size, length), strides=(stride, 1), writeable=False
                )
                blocks.append(view)
            else:
                blocks.append(arr[(dpos + 4)[:, None] + np.arange(length)])
        order = np.argsort(idx[:, 0], kind="stable")
        return idx[order, 0], np.concatenate(blocks)[order]
    except Exception:  # noqa: BLE001 - any surprise in the private layout: use the generic reader
        return None


def _verified(reader, raws: list, msgtype: str, decoded: tuple, rows: list[int]) -> bool:
    """The fast decoding of ``rows`` equals the library's deserialisation of ``raws`` (same order)."""
    for raw, j in zip(raws, rows):
        ns, w, a = _msg_values(reader.deserialize(raw, msgtype))
        if ns != decoded[0][j] or not (np.array_equal(w, decoded[1][j]) and np.array_equal(a, decoded[2][j])):
            return False
    return True


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
            ok = _verified(reader, [raws[idx[0]], raws[idx[-1]]], msgtype, fast, [0, idx.size - 1])
        if ok:
            stamp[idx], gyro[idx], accel[idx] = fast[0], fast[1], fast[2]
        else:
            for i in idx:
                stamp[i], gyro[i], accel[i] = _msg_values(reader.deserialize(raws[i], msgtype))
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
    reader = _open(path)
    try:
        topics = _topics(reader)
        name = _choose_topic(path, topics, topic, IMU_TYPES, "IMU")
        conns = [c for c in reader.connections if c.topic == name]
        msgtype = conns[0].msgtype
        fast = _ros1_blocks(reader, conns)
        if fast is not None:
            bag_ns, block = fast
            raws = [block[0].tobytes(), block[-1].tobytes()]
            decoded = _decode_block(block, ros1=True)
            if decoded is None or not _verified(reader, raws, msgtype, decoded, [0, -1]):
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


def imu_topic(path: str | Path, topic: str | None = None) -> BagTopic:
    """The ``sensor_msgs/Imu`` topic :func:`read_imu_bag` would read (name, type, message count)."""
    path = Path(path)
    topics = list_topics(path)
    name = _choose_topic(path, topics, topic, IMU_TYPES, "IMU")
    return next(t for t in topics if t.name == name)


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
    reader = _open(path)
    try:
        name = _choose_topic(path, _topics(reader), topic, IMU_TYPES, "IMU")
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
    reader = _open(path)
    try:
        topics = _topics(reader)
        name = _choose_topic(path, topics, topic, NAVSAT_TYPES, "NavSatFix")
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


# ----------------------------------------------------------------------------------------------
# writers (simulations, tests, converting CSV logs to bags)
# ----------------------------------------------------------------------------------------------
def _imu_records(stamp_ns: np.ndarray, gyro: np.ndarray, accel: np.ndarray, frame_id: str, ros1: bool) -> np.ndarray:
    """Serialised sensor_msgs/Imu messages (n, size) for the fixed layout of :func:`_decode_block`."""
    fid = frame_id.encode()
    n = stamp_ns.size
    sec = stamp_ns // 1_000_000_000
    nsec = stamp_ns - sec * 1_000_000_000
    if ros1:
        off = _ros1_offsets(len(fid))
        rec = np.zeros((n, off["size"]), dtype=np.uint8)
        rec[:, 0:4] = np.arange(n, dtype="<u4").view(np.uint8).reshape(n, 4)  # seq
        rec[:, 12:16] = np.frombuffer(np.uint32(len(fid)).astype("<u4").tobytes(), np.uint8)
        rec[:, 16 : 16 + len(fid)] = np.frombuffer(fid, np.uint8)
        sec_t = "<u4"
        q = 16 + len(fid)
    else:
        off = _cdr_offsets(len(fid) + 1)
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
) -> Path:
    """Write ``sensor_msgs/Imu`` messages (``t`` s as float, or integer ns; ``gyro`` rad/s, ``accel`` m/s²,
    (n, 3)) to a bag whose format follows the suffix: ``.bag`` ROS 1 (Noetic types); ``.db3`` / ``.mcap``
    a ROS 2 (Humble) bag folder ``<stem>/`` holding ``<stem>.db3`` / ``<stem>.mcap`` and metadata.yaml —
    the storage file's path is returned; any other name: a ROS 2 sqlite3 bag folder. Header stamp = bag time = ``t``.
    ``navsat`` = (t, lat_deg, lon_deg, alt_m[, cov (n, 9) ENU m²[, status (n,)]]) adds a NavSatFix topic
    (``t`` s or integer ns; status 0 = fix, −1 = no fix)."""
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
        if navsat is None:
            for ns, row in zip(stamp.tolist(), rec):
                writer.write(conn, ns, row.tobytes())
            return result
        nav_conn = writer.add_connection(navsat_topic, "sensor_msgs/msg/NavSatFix", typestore=typestore)
        events: list[tuple[int, int, Any]] = [(ns, 0, i) for i, ns in enumerate(stamp.tolist())]
        events += [(ns, 1, raw) for ns, raw in _navsat_messages(typestore, navsat, ros1)]
        events.sort(key=lambda e: (e[0], e[1]))
        for ns, kind, item in events:
            writer.write(conn, ns, rec[item].tobytes()) if kind == 0 else writer.write(nav_conn, ns, item)
    return result
