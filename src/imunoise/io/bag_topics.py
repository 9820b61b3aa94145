"""Bag files and their topics: what counts as a bag, opening one with ``rosbags`` (ROS 1 ``.bag``, ROS 2
``.db3``/``.mcap`` or a bag folder) and choosing the IMU or NavSatFix topic to read
(docs/guide/theory.rst, 'Interfaces')."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from imunoise.errors import DataError

__all__ = [
    "BAG_SUFFIXES",
    "IMU_TYPES",
    "NAVSAT_TYPES",
    "BagTopic",
    "choose_topic",
    "imu_topic",
    "is_bag",
    "list_topics",
    "open_bag",
    "topics_of",
]

BAG_SUFFIXES = (".bag", ".db3", ".mcap")
IMU_TYPES = ("sensor_msgs/msg/Imu", "sensor_msgs/Imu")
NAVSAT_TYPES = ("sensor_msgs/msg/NavSatFix", "sensor_msgs/NavSatFix")


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


def open_bag(path: Path):
    from rosbags.highlevel import AnyReaderError

    reader = _reader(path)
    try:
        reader.open()
    except (AnyReaderError, Exception) as exc:  # rosbags raises several unrelated types on bad files
        if isinstance(exc, FileNotFoundError):
            raise
        raise DataError(f"cannot read ROS bag {path}: {exc}") from exc
    return reader


def topics_of(reader) -> list[BagTopic]:
    counts: dict[tuple[str, str], int] = {}
    for c in reader.connections:
        key = (c.topic, c.msgtype)
        counts[key] = counts.get(key, 0) + max(int(c.msgcount), 0)
    return [BagTopic(t, m, n) for (t, m), n in sorted(counts.items())]


def list_topics(path: str | Path) -> list[BagTopic]:
    """Topics of a bag with their message type and count."""
    reader = open_bag(Path(path))
    try:
        return topics_of(reader)
    finally:
        reader.close()


def choose_topic(path: Path, topics: list[BagTopic], topic: str | None, types: tuple[str, ...], what: str,
                 option: str = "--topic") -> str:
    """The topic to read: ``topic`` if it carries one of ``types``, else the only such topic (``option`` chooses
    among several)."""
    listing = "\n  ".join(str(t) for t in topics) or "(none)"
    matching = [t for t in topics if t.msgtype in types]
    if topic is None:
        if len(matching) == 1:
            return matching[0].name
        if not matching:
            raise DataError(f"{path} has no {what} topic ({types[0]}); its topics are:\n  {listing}")
        raise DataError(f"{path} has {len(matching)} {what} topics; choose one with {option}. Topics:\n  {listing}")
    names = {t.name: t for t in topics}
    if topic not in names:
        raise DataError(f"{path} has no topic {topic!r}; its topics are:\n  {listing}")
    if names[topic].msgtype not in types:
        raise DataError(
            f"topic {topic!r} of {path} carries {names[topic].msgtype}, not {types[0]}; topics:\n  {listing}"
        )
    return topic


def imu_topic(path: str | Path, topic: str | None = None) -> BagTopic:
    """The ``sensor_msgs/Imu`` topic :func:`read_imu_bag` would read (name, type, message count)."""
    path = Path(path)
    topics = list_topics(path)
    name = choose_topic(path, topics, topic, IMU_TYPES, "IMU")
    return next(t for t in topics if t.name == name)
