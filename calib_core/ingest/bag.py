"""Open a ROS 1 / ROS 2 bag with ``rosbags`` (no ROS install) and choose its topics.

``SOURCE`` may be a ROS 1 ``.bag`` file, a ROS 2 bag folder (``metadata.yaml`` plus
``.db3`` / ``.mcap``), or one ``.db3`` / ``.mcap`` file of such a folder. Every problem
(missing or truncated bag, unknown topic, no images) is a :class:`SessionError` naming the bag.
"""

from __future__ import annotations

import contextlib
import re
from dataclasses import dataclass
from pathlib import Path

from calib_core.errors import SessionError
from calib_core.ingest import rosmsg

BAG_SUFFIXES = (".bag", ".db3", ".mcap")


@dataclass(frozen=True)
class TopicRow:
    topic: str
    msgtype: str
    count: int


@dataclass(frozen=True)
class CameraTopics:
    name: str
    image_topic: str
    image_type: str
    info_topic: str | None


def bag_path(source: str | Path) -> Path:
    """The path ``rosbags`` opens: a ``.bag`` file or a ROS 2 bag folder."""
    p = Path(source)
    if not p.exists():
        raise SessionError(p, "bag not found")
    if p.is_file() and p.suffix.lower() in (".db3", ".mcap") and (p.parent / "metadata.yaml").is_file():
        return p.parent
    if p.is_file() and p.suffix.lower() not in BAG_SUFFIXES:
        raise SessionError(p, f"not a bag (expected {', '.join(BAG_SUFFIXES)} or a ROS 2 bag folder)")
    if p.is_dir() and not (p / "metadata.yaml").is_file():
        raise SessionError(p, "folder is not a ROS 2 bag (no metadata.yaml)")
    return p


@contextlib.contextmanager
def open_bag(source: str | Path):
    """``with open_bag(path) as reader:`` an opened ``rosbags`` AnyReader; read errors -> SessionError."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    p = bag_path(source)
    try:
        reader = AnyReader([p], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except SessionError:
        raise
    except Exception as e:
        raise SessionError(p, f"cannot open bag (truncated or corrupt?): {_why(e)}") from None
    try:
        yield reader
    finally:
        with contextlib.suppress(Exception):
            reader.close()


def _why(e: Exception) -> str:
    text = str(e).splitlines()[0] if str(e) else type(e).__name__
    return text[:160]


def read_error(path, e: Exception) -> SessionError:
    """The error for a failure while reading messages (a truncated or corrupt bag)."""
    return SessionError(path, f"cannot read bag (truncated or corrupt?): {type(e).__name__}: {_why(e)}")


def list_topics(reader) -> list[TopicRow]:
    return [TopicRow(t, info.msgtype, int(info.msgcount)) for t, info in sorted(reader.topics.items())]


def pick_sonar_topic(path, rows: list[TopicRow], wanted: str | None) -> str:
    clouds = [r.topic for r in rows if r.msgtype == rosmsg.POINTCLOUD2]
    if wanted is not None:
        _check_topic(path, rows, wanted, (rosmsg.POINTCLOUD2,))
        return wanted
    if not clouds:
        raise SessionError(path, "bag has no sensor_msgs/PointCloud2 topic (no sonar data)")
    if len(clouds) > 1:
        raise SessionError(path, f"several PointCloud2 topics ({', '.join(clouds)}): choose one with --sonar-topic")
    return clouds[0]


def _check_topic(path, rows: list[TopicRow], topic: str, types: tuple[str, ...]) -> None:
    by = {r.topic: r for r in rows}
    if topic not in by:
        raise SessionError(path, f"unknown topic '{topic}' (topics: {', '.join(by) or 'none'})")
    if by[topic].msgtype not in types:
        raise SessionError(path, f"topic '{topic}' is {by[topic].msgtype}, expected {' or '.join(types)}")


GENERIC_TOPIC_WORDS = ("image_raw", "image", "compressed", "image_color", "image_rect", "image_rect_color", "color",
                       "rgb")


def camera_name(topic: str, taken: set[str]) -> str:
    """``/cam1/image_raw`` -> ``cam1``, ``/stereo/left/image_raw`` -> ``stereo_left``: unique and session-safe."""
    parts = [p for p in topic.split("/") if p and p not in GENERIC_TOPIC_WORDS]
    base = re.sub(r"[^A-Za-z0-9_-]", "_", "_".join(parts) if parts else "cam")[:60] or "cam"
    name, i = base, 2
    while name in taken:
        name, i = f"{base}_{i}", i + 1
    return name


def pick_cameras(path, rows: list[TopicRow], wanted: list[str] | None) -> list[CameraTopics]:
    """Camera image topics (given as ``TOPIC`` or ``NAME=TOPIC``, else all image topics), each with
    the CameraInfo topic that shares the longest namespace with it."""
    images = [r for r in rows if r.msgtype in rosmsg.IMAGE_TYPES]
    infos = [r.topic for r in rows if r.msgtype == rosmsg.CAMERA_INFO]
    if wanted:
        chosen = []
        for w in wanted:
            name, _, topic = w.rpartition("=")
            if name and not re.fullmatch(r"[A-Za-z0-9_.-]{1,64}", name) or name in (".", ".."):
                raise SessionError(path, f"camera name {name!r} must be letters, digits, '_', '-' or '.'")
            _check_topic(path, rows, topic, rosmsg.IMAGE_TYPES)
            chosen.append((name or None, topic))
    else:
        if not images:
            raise SessionError(path, "bag has no camera images (no sensor_msgs/Image or CompressedImage topic)")
        raw_ns = {_namespace(r.topic) for r in images if r.msgtype == rosmsg.IMAGE}
        chosen = [(None, r.topic) for r in images
                  if r.msgtype == rosmsg.IMAGE or _namespace(r.topic) not in raw_ns]
    types = {r.topic: r.msgtype for r in rows}
    out, taken = [], set()
    for name, topic in chosen:
        name = name or camera_name(topic, taken)
        taken.add(name)
        out.append(CameraTopics(name, topic, types[topic], _best_info(topic, infos)))
    return out


def _namespace(topic: str) -> str:
    t = topic[: -len("/compressed")] if topic.endswith("/compressed") else topic
    return t.rsplit("/", 1)[0]


def _best_info(image_topic: str, infos: list[str]) -> str | None:
    ns = _namespace(image_topic)
    best, score = None, -1
    for t in infos:
        common = len(_common_prefix(ns.split("/"), t.rsplit("/", 1)[0].split("/")))
        if common > score and common > 1:
            best, score = t, common
    return best


def _common_prefix(a: list[str], b: list[str]) -> list[str]:
    out = []
    for x, y in zip(a, b):
        if x != y:
            break
        out.append(x)
    return out
