"""A small writer for ROS 1 ``.bag`` and ROS 2 (``.mcap`` / ``.db3``) bags, over ``rosbags``.

Used by the synthetic bag writer and the benchmarks; it serialises message objects built
by :mod:`calib_core.ingest.rosmsg` with the matching type store (ROS 1 Noetic, ROS 2 Humble).
"""

from __future__ import annotations

from pathlib import Path

BAG_KINDS = ("ros2", "ros2-db3", "ros1")


class BagWriter:
    """``with BagWriter(path, kind) as w: c = w.connection(topic, msgtype); w.write(c, t_ns, msg)``.

    ``kind``: "ros2" (MCAP storage; ``path`` is the bag folder), "ros2-db3" (SQLite storage),
    "ros1" (``path`` is the ``.bag`` file). The path must not exist yet.
    """

    def __init__(self, path: str | Path, kind: str = "ros2"):
        from rosbags.typesys import Stores, get_typestore

        if kind not in BAG_KINDS:
            raise ValueError(f"unknown bag kind {kind!r}; use one of {BAG_KINDS}")
        self.path, self.kind = Path(path), kind
        self.ros1 = kind == "ros1"
        self.typestore = get_typestore(Stores.ROS1_NOETIC if self.ros1 else Stores.ROS2_HUMBLE)
        if "tf2_msgs/msg/TFMessage" not in self.typestore.types:  # the Noetic store lacks tf2_msgs
            from rosbags.typesys import get_types_from_msg

            self.typestore.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms",
                                                       "tf2_msgs/msg/TFMessage"))
        if self.ros1:
            from rosbags.rosbag1 import Writer

            self._w = Writer(self.path)
        else:
            from rosbags.rosbag2 import StoragePlugin, Writer

            plugin = StoragePlugin.MCAP if kind == "ros2" else StoragePlugin.SQLITE3
            self._w = Writer(self.path, version=9, storage_plugin=plugin)
        self._conns = {}

    def __enter__(self) -> "BagWriter":
        self._w.open()
        return self

    def __exit__(self, *exc) -> None:
        self._w.close()

    def connection(self, topic: str, msgtype: str, latching: bool = False):
        if topic not in self._conns:
            kw = {"latching": 1} if (self.ros1 and latching) else {}
            self._conns[topic] = self._w.add_connection(topic, msgtype, typestore=self.typestore, **kw)
        return self._conns[topic]

    def write(self, topic: str, msgtype: str, t_ns: int, msg) -> None:
        conn = self.connection(topic, msgtype)
        ser = self.typestore.serialize_ros1 if self.ros1 else self.typestore.serialize_cdr
        self._w.write(conn, int(t_ns), ser(msg, msgtype))
