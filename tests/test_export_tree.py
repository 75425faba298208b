"""Every ROS export is one valid transform tree, whichever parent is asked for.

The outputs are read back the way their consumers read them: tf2 keeps one parent per child
frame (a second parent replaces the first, which breaks lookups) and needs an acyclic tree;
urdfdom parses the XML, requires every joint's links to exist, each link to be the child of
at most one joint and exactly one root link. Chaining the published transforms from any
camera to the sonar must give back the calibration's T_cam_sonar.
"""

from __future__ import annotations

import shlex
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from calib_core.export import FrameNames, export_text
from calib_core.geometry import T_from_rotvec, invert_T


def _calibration(n_cams: int) -> dict:
    rng = np.random.default_rng(n_cams)
    return {"format": "sonar-camera-calibration/1", "cameras": {
        f"cam{k + 1}": {"T_cam_sonar": T_from_rotvec(rng.normal(size=3), rng.normal(size=3)).tolist()}
        for k in range(n_cams)}}


def _T(xyz, q_xyzw) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(q_xyzw).as_matrix()
    T[:3, 3] = xyz
    return T


def _rpy(r, p, y) -> np.ndarray:
    return Rotation.from_euler("xyz", [r, p, y]).as_matrix()


def parse_tf_static(text: str) -> list[tuple[str, str, np.ndarray]]:
    out = []
    for line in text.splitlines():
        if line.startswith("rosrun"):
            t = shlex.split(line.rstrip("&"))[3:]
            nums = [float(v) for v in t[:7]]
            out.append((t[7], t[8], _T(nums[:3], nums[3:])))
    return out


def parse_tf2_yaml(text: str) -> list[tuple[str, str, np.ndarray]]:
    out = []
    for tf in yaml.safe_load(text)["transforms"]:
        tr, r = tf["transform"]["translation"], tf["transform"]["rotation"]
        out.append((tf["header"]["frame_id"], tf["child_frame_id"],
                    _T([tr["x"], tr["y"], tr["z"]], [r["x"], r["y"], r["z"], r["w"]])))
    return out


def parse_urdf(text: str) -> list[tuple[str, str, np.ndarray]]:
    robot = ET.fromstring(text.split("?>", 1)[1])  # raises on invalid XML
    assert robot.tag == "robot" and robot.get("name")
    links = [ln.get("name") for ln in robot.findall("link")]
    assert len(links) == len(set(links)), "duplicate link names"
    out, names = [], set()
    for j in robot.findall("joint"):
        assert j.get("name") not in names, "duplicate joint names"
        names.add(j.get("name"))
        parent, child = j.find("parent").get("link"), j.find("child").get("link")
        assert parent in links and child in links, "a joint names a link that does not exist"
        o = j.find("origin")
        T = np.eye(4)
        T[:3, :3] = _rpy(*[float(v) for v in o.get("rpy").split()])
        T[:3, 3] = [float(v) for v in o.get("xyz").split()]
        out.append((parent, child, T))
    assert len(links) == len(out) + 1, "a URDF tree has one more link than joints"
    return out


def check_tree(edges) -> dict:
    """{child: (parent, T_parent_child)}; asserts one parent per child, no cycle, one root."""
    tree = {}
    for parent, child, T in edges:
        assert child not in tree, f"'{child}' has two parents ({tree.get(child, [None])[0]} and {parent})"
        tree[child] = (parent, T)
    frames = set(tree) | {p for p, _c, _T in edges}
    roots = frames - set(tree)
    assert len(roots) == 1, f"expected one root, got {sorted(roots)}"
    for f in frames:
        seen = set()
        while f in tree:
            assert f not in seen, "cycle"
            seen.add(f)
            f = tree[f][0]
    return tree


def T_root_frame(tree: dict, frame: str) -> np.ndarray:
    T = np.eye(4)
    while frame in tree:
        parent, T_pc = tree[frame]
        T = T_pc @ T
        frame = parent
    return T


PARSERS = {"tf-static": parse_tf_static, "tf2-yaml": parse_tf2_yaml, "urdf": parse_urdf}


@pytest.mark.parametrize("fmt", list(PARSERS))
@pytest.mark.parametrize("parent", ["sonar", "camera"])
@pytest.mark.parametrize("n_cams", [1, 2, 3])
def test_export_is_one_tree(fmt, parent, n_cams):
    cal = _calibration(n_cams)
    frames = FrameNames(parent=parent)
    tree = check_tree(PARSERS[fmt](export_text(cal, fmt, frames=frames)))
    assert len(tree) == n_cams
    for cam, c in cal["cameras"].items():
        T_root_cam = T_root_frame(tree, f"{cam}_optical_frame")
        T_root_sonar = T_root_frame(tree, "sonar")
        T_cam_sonar = invert_T(T_root_cam) @ T_root_sonar
        np.testing.assert_allclose(T_cam_sonar, np.asarray(c["T_cam_sonar"]), atol=1e-9)


def test_check_tree_catches_two_parents():
    """The checker itself must fail on the old output (sonar below two cameras)."""
    edges = [("cam1", "sonar", np.eye(4)), ("cam2", "sonar", np.eye(4))]
    with pytest.raises(AssertionError, match="two parents"):
        check_tree(edges)
