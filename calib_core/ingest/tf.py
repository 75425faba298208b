"""``/tf_static`` -> the stereo transform between two cameras' frames.

A TransformStamped with parent frame P (``header.frame_id``) and child C gives C's pose in P:
``T_P_C`` (maps points in C into P). The static transforms form a tree; the transform
between two frames composes the edges on the path between them.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from scipy.spatial.transform import Rotation

from calib_core.geometry import invert_T, make_T
from calib_core.ingest.rosmsg import header_msg


def edges_from_msgs(msgs) -> dict[tuple[str, str], np.ndarray]:
    """{(parent, child): T_parent_child} from TFMessage objects (later ones replace earlier)."""
    out = {}
    for m in msgs:
        for tr in m.transforms:
            t, q = tr.transform.translation, tr.transform.rotation
            R = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
            out[(tr.header.frame_id.lstrip("/"), tr.child_frame_id.lstrip("/"))] = make_T(R, [t.x, t.y, t.z])
    return out


def transform_between(edges: dict, target: str, source: str) -> np.ndarray | None:
    """T_target_source through the static tree, or None when the frames are not connected."""
    target, source = target.lstrip("/"), source.lstrip("/")
    graph: dict[str, list[tuple[str, np.ndarray]]] = {}
    for (p, c), T_pc in edges.items():
        graph.setdefault(p, []).append((c, T_pc))  # moving from p to c: T_p_c maps c -> p
        graph.setdefault(c, []).append((p, invert_T(T_pc)))
    # breadth-first from target; T accumulates T_target_node
    seen = {target: np.eye(4)}
    queue = deque([target])
    while queue:
        node = queue.popleft()
        if node == source:
            return seen[node]
        for nxt, T_node_nxt in graph.get(node, []):
            if nxt not in seen:
                seen[nxt] = seen[node] @ T_node_nxt
                queue.append(nxt)
    return None


def tf_static_msg(ts, stamp: int, parent: str, child: str, T_parent_child: np.ndarray, ros1: bool):
    """A TFMessage with one transform (for synthetic bags)."""
    q = Rotation.from_matrix(T_parent_child[:3, :3]).as_quat()
    t = T_parent_child[:3, 3]
    tr = ts.types["geometry_msgs/msg/Transform"](
        translation=ts.types["geometry_msgs/msg/Vector3"](x=float(t[0]), y=float(t[1]), z=float(t[2])),
        rotation=ts.types["geometry_msgs/msg/Quaternion"](x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])))
    st = ts.types["geometry_msgs/msg/TransformStamped"](header=header_msg(ts, stamp, parent, ros1), child_frame_id=child,
                                                        transform=tr)
    return ts.types["tf2_msgs/msg/TFMessage"](transforms=[st])
