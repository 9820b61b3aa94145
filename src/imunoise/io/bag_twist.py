"""Twist topics of a bag: ``geometry_msgs/TwistStamped``, ``geometry_msgs/TwistWithCovarianceStamped`` and
``nav_msgs/Odometry`` (docs/guide/theory.rst, 'Interfaces'): what a GNSS receiver's velocity (ENU, e.g.
``/ublox/fix_velocity``) and a vehicle's wheel speed (body x, forward) are published as.

:func:`read_twist_topic` gives the header stamps [s], the linear velocity (n, 3) as the message holds it (the
caller knows the frame) and its variance (n, 3) where the message has a covariance with positive diagonal (else
NaN). :func:`twist_messages` serialises such messages for :func:`imunoise.io.bag_write.write_imu_bag`.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import NamedTuple

import numpy as np

from imunoise.errors import DataError
from imunoise.io.bag_topics import choose_topic, open_bag, topics_of

__all__ = ["TWIST_TYPES", "TwistTopic", "read_twist_topic", "twist_messages"]

TWIST_TYPES = ("geometry_msgs/msg/TwistStamped", "geometry_msgs/TwistStamped",
               "geometry_msgs/msg/TwistWithCovarianceStamped", "geometry_msgs/TwistWithCovarianceStamped",
               "nav_msgs/msg/Odometry", "nav_msgs/Odometry")


class TwistTopic(NamedTuple):
    """A twist topic read: header stamps [s], linear velocity (n, 3) [m/s], its variance (n, 3) [m²/s²] (NaN
    without a covariance), the topic's name and message type."""

    t: np.ndarray
    linear: np.ndarray
    var: np.ndarray
    topic: str
    msgtype: str


def _linear(m) -> tuple[np.ndarray, np.ndarray]:
    """(linear velocity, variance) of a TwistStamped / TwistWithCovarianceStamped / Odometry message."""
    tw = m.twist.twist if hasattr(m, "child_frame_id") or hasattr(m.twist, "covariance") else m.twist
    lin = np.array([tw.linear.x, tw.linear.y, tw.linear.z], dtype=float)
    cov = getattr(m.twist, "covariance", None)
    var = np.full(3, np.nan) if cov is None else np.asarray(cov, dtype=float)[[0, 7, 14]]
    return lin, np.where(var > 0, var, np.nan)


def read_twist_topic(path: str | Path, topic: str | None, what: str) -> TwistTopic:
    """The twist topic ``topic`` of the bag ``path`` (or its only twist topic); ``what`` names the measurement in
    the messages (e.g. ``--gnss-vel``)."""
    path = Path(path)
    reader = open_bag(path)
    try:
        topics = topics_of(reader)
        name = choose_topic(path, topics, topic, TWIST_TYPES, f"{what} twist",
                            f"{what}-topic" if what.startswith("--") else "--topic")
        conns = [c for c in reader.connections if c.topic == name]
        stamps, lin, var = [], [], []
        msgtype = conns[0].msgtype
        for conn, _, raw in reader.messages(connections=conns):
            m = reader.deserialize(raw, conn.msgtype)
            st = m.header.stamp
            stamps.append(int(st.sec) * 1_000_000_000 + int(getattr(st, "nanosec", getattr(st, "nsec", 0))))
            v, s2 = _linear(m)
            lin.append(v)
            var.append(s2)
    finally:
        reader.close()
    if not stamps:
        raise DataError(f"topic {name!r} of {path} ({what}) has no messages")
    return TwistTopic(np.array(stamps, dtype=np.int64) / 1e9, np.array(lin), np.array(var), name, msgtype)


def twist_messages(typestore, t, linear, var, ros1: bool) -> Iterable[tuple[int, bytes, str]]:
    """Serialised twist messages ``(stamp ns, bytes, msgtype)``: TwistWithCovarianceStamped when ``var`` (n, 3)
    is given, else TwistStamped; ``t`` [s] or integer ns, ``linear`` (n, 3) [m/s]."""
    t = np.asarray(t)
    stamps = t.astype(np.int64) if np.issubdtype(t.dtype, np.integer) else np.round(t * 1e9).astype(np.int64)
    linear = np.asarray(linear, dtype=float).reshape(-1, 3)
    T = typestore.types
    msgtype = "geometry_msgs/msg/TwistStamped" if var is None else "geometry_msgs/msg/TwistWithCovarianceStamped"
    for i in range(stamps.size):
        ns = int(stamps[i])
        hdr = {"stamp": T["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000),
               "frame_id": "base_link"}
        if ros1:
            hdr["seq"] = i
        zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        twist = T["geometry_msgs/msg/Twist"](linear=T["geometry_msgs/msg/Vector3"](*map(float, linear[i])),
                                             angular=zero)
        if var is None:
            msg = T[msgtype](header=T["std_msgs/msg/Header"](**hdr), twist=twist)
        else:
            cov = np.zeros(36)
            cov[[0, 7, 14]] = np.asarray(var, dtype=float).reshape(-1, 3)[i]
            msg = T[msgtype](header=T["std_msgs/msg/Header"](**hdr),
                             twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=cov))
        raw = typestore.serialize_ros1(msg, msgtype) if ros1 else typestore.serialize_cdr(msg, msgtype)
        yield ns, bytes(raw), msgtype
