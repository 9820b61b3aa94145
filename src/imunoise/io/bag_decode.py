"""Fast decoding of ``sensor_msgs/Imu`` messages from a bag's raw bytes (docs/guide/theory.rst, 'Interfaces').

Reading millions of IMU messages through the generic deserialiser costs ~20 µs each; all messages of
one length share one layout, so they are decoded at once with NumPy from the raw bytes at the field
offsets of the ROS 1 / little-endian CDR layout. The offsets are checked against the ``rosbags``
deserialiser on the first and last message of each layout, and the generic path is used if they differ.
"""

from __future__ import annotations

import itertools

import numpy as np

__all__ = ["cdr_offsets", "decode_block", "msg_values", "ros1_blocks", "ros1_offsets", "verified"]


def ros1_offsets(frame_len: int) -> dict[str, int]:
    # seq u32, sec u32, nsec u32, frame_id (u32 length + bytes), then packed float64 (no alignment)
    q = 16 + frame_len
    av = q + 32 + 72
    return {"sec": 4, "nsec": 8, "av": av, "la": av + 24 + 72, "size": av + 24 + 72 + 24 + 72}


def cdr_offsets(frame_len_with_nul: int) -> dict[str, int]:
    # 4-byte encapsulation header; then sec i32, nanosec u32, frame_id (u32 length incl. NUL + bytes),
    # float64s aligned to 8 relative to the end of the encapsulation header
    p = 12 + frame_len_with_nul
    q = 4 + ((p + 7) // 8) * 8
    av = q + 32 + 72
    return {"sec": 4 + 0, "nsec": 4 + 4, "av": av, "la": av + 24 + 72, "size": av + 24 + 72 + 24 + 72}


def _f8(block: np.ndarray, off: int, k: int) -> np.ndarray:
    return np.ascontiguousarray(block[:, off : off + 8 * k]).view("<f8").reshape(-1, k)


def decode_block(block: np.ndarray, ros1: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, int] | None:
    """(stamp_ns, gyro, accel, frame_len) for messages of one length, or None if the layout is not ours."""
    n, length = block.shape
    if ros1:
        flen = int(block[0, 12:16].view("<u4")[0])
        off = ros1_offsets(flen)
    else:
        if block[0, 1] != 1:  # big-endian CDR: leave it to the generic deserialiser
            return None
        flen = int(block[0, 12:16].view("<u4")[0])
        off = cdr_offsets(flen)
    if off["size"] != length:
        return None
    sec = np.ascontiguousarray(block[:, off["sec"] : off["sec"] + 4]).view("<u4" if ros1 else "<i4")
    nsec = np.ascontiguousarray(block[:, off["nsec"] : off["nsec"] + 4]).view("<u4")
    stamp = sec.astype(np.int64).ravel() * 1_000_000_000 + nsec.astype(np.int64).ravel()
    return stamp, _f8(block, off["av"], 3), _f8(block, off["la"], 3), flen


def msg_values(msg) -> tuple[int, np.ndarray, np.ndarray]:
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


def ros1_blocks(reader, conns) -> tuple[np.ndarray, np.ndarray] | None:
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


def verified(reader, raws: list, msgtype: str, decoded: tuple, rows: list[int]) -> bool:
    """The fast decoding of ``rows`` equals the library's deserialisation of ``raws`` (same order)."""
    for raw, j in zip(raws, rows):
        ns, w, a = msg_values(reader.deserialize(raw, msgtype))
        if ns != decoded[0][j] or not (np.array_equal(w, decoded[1][j]) and np.array_equal(a, decoded[2][j])):
            return False
    return True
