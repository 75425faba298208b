"""session.yaml: parsing, structural errors, path confinement, validate_session."""

from __future__ import annotations

import os

import numpy as np
import pytest
from conftest import edit_yaml

from calib_core.errors import SessionError
from calib_core.session import load_session, parse_transform, resolve_inside, validate_session


def edit_manifest(root, fn):
    edit_yaml(root / "session.yaml", fn)


def test_load_minimal_session(make_session, tmp_path):
    root = make_session(tmp_path, n_captures=3, cameras=("cam1", "cam2"))
    s = load_session(root)
    assert s.root == root.resolve() and s.name == "test-session"
    assert s.sphere_diameter_m == 0.22 and s.sphere_radius_m == 0.11
    assert list(s.cameras) == ["cam1", "cam2"] and [c.id for c in s.captures] == ["p01", "p02", "p03"]
    assert s.captures[0].cloud_path == root.resolve() / "clouds" / "p01.ply"
    assert s.captures[1].image_paths["cam2"] == root.resolve() / "images" / "cam2" / "p02.png"
    assert s.sound_speed_m_s == 1481.0 and s.beam_width_deg == 1.0 and s.sonar_model == "test sonar"
    assert s.capture("p02").id == "p02"
    with pytest.raises(SessionError, match="no capture 'p09'"):
        s.capture("p09")
    assert s.camera_model("cam1").width_px == 64
    # the manifest itself may be given instead of the folder
    assert load_session(root / "session.yaml").root == s.root


def test_optional_extensions(make_session, tmp_path):
    root = make_session(tmp_path, cameras=("cam1", "cam2"), background=True)
    T = np.eye(4)
    T[0, 3] = -0.74

    def fn(d):
        d["measured"] = {"cam1-sonar": 0.8656, "cam1-cam2": 0.7437}
        d["stereo"] = {"T_cam2_cam1": T.tolist()}
        d["sonar"]["beam_width_deg"] = 1.5
        d["cameras"]["cam1"]["background_window"] = [1.0, 4.5]
        d["captures"][0]["images"] = {}  # a capture without images is allowed
        d["captures"][1]["id"] = 7  # ids may be numbers in YAML
        del d["format"]  # format is optional
        del d["name"]
    edit_manifest(root, fn)
    s = load_session(root)
    assert s.measured_m == {"cam1-sonar": 0.8656, "cam1-cam2": 0.7437}
    np.testing.assert_array_equal(s.stereo["T_cam2_cam1"], T)
    assert s.beam_width_deg == 1.5 and s.cameras["cam1"].background_window_s == (1.0, 4.5)
    assert s.cameras["cam1"].background_path == root.resolve() / "backgrounds" / "cam1"
    assert s.captures[0].image_paths == {} and s.captures[1].id == "7"
    assert s.name == "session"  # the folder name when 'name' is absent


BAD_EDITS = {
    "no sphere": (lambda d: d.pop("sphere"), "missing 'sphere"),
    "negative diameter": (lambda d: d["sphere"].update(diameter=-0.22), "sphere.diameter must be a positive"),
    "zero diameter": (lambda d: d["sphere"].update(diameter=0), "sphere.diameter must be a positive"),
    "diameter in mm": (lambda d: d["sphere"].update(diameter=220), "implausible"),
    "diameter text": (lambda d: d["sphere"].update(diameter="22 cm"), "must be a number"),
    "diameter bool": (lambda d: d["sphere"].update(diameter=True), "must be a number"),
    "diameter nan": (lambda d: d["sphere"].update(diameter=float("nan")), "finite"),
    "huge int": (lambda d: d["sphere"].update(diameter=10**400), "finite"),
    "sound speed in air": (lambda d: d["sonar"].update(sound_speed=343), "outside water"),
    "beam width": (lambda d: d["sonar"].update(beam_width_deg=90), "implausible"),
    "sonar list": (lambda d: d.update(sonar=[1, 2]), "'sonar' must be a mapping"),
    "wrong format": (lambda d: d.update(format="something-else/1"), "not a sonar-camera-session"),
    "future format": (lambda d: d.update(format="sonar-camera-session/2"), "not one this tool understands"),
    "format number": (lambda d: d.update(format=1), "not a sonar-camera-session"),
    "no cameras": (lambda d: d.pop("cameras"), "missing 'cameras'"),
    "cameras list": (lambda d: d.update(cameras=["cam1"]), "missing 'cameras'"),
    "camera named sonar": (lambda d: d["cameras"].update(sonar={"intrinsics": "intrinsics/cam1.yaml"}), "may not be called 'sonar'"),
    "no intrinsics": (lambda d: d["cameras"]["cam1"].pop("intrinsics"), "missing 'intrinsics"),
    "intrinsics number": (lambda d: d["cameras"]["cam1"].update(intrinsics=5), "expected a relative path"),
    "bad window": (lambda d: d["cameras"]["cam1"].update(background_window=[1]), "background_window"),
    "no captures": (lambda d: d.pop("captures"), "missing 'captures'"),
    "empty captures": (lambda d: d.update(captures=[]), "missing 'captures'"),
    "capture not mapping": (lambda d: d["captures"].append("p09"), "must be a mapping"),
    "capture no id": (lambda d: d["captures"][0].pop("id"), "missing 'id'"),
    "duplicate id": (lambda d: d["captures"][1].update(id="p01"), "duplicate id 'p01'"),
    "no cloud": (lambda d: d["captures"][0].pop("cloud"), "missing 'cloud'"),
    "images list": (lambda d: d["captures"][0].update(images=["a.png"]), "'images' must map"),
    "unknown camera": (lambda d: d["captures"][0]["images"].update(cam9="images/x.png"), "unknown camera 'cam9'"),
    "measured list": (lambda d: d.update(measured=[0.8]), "'measured' must be a mapping"),
    "measured negative": (lambda d: d.update(measured={"cam1-sonar": -1}), "measured.cam1-sonar"),
    "stereo list": (lambda d: d.update(stereo=[1]), "'stereo' must be a mapping"),
    "stereo 3x3": (lambda d: d.update(stereo={"T_cam2_cam1": np.eye(3).tolist()}), "finite 4x4"),
    "stereo not rigid": (lambda d: d.update(stereo={"T_cam2_cam1": (np.eye(4) * 2).tolist()}), "not a rigid"),
    "stereo text": (lambda d: d.update(stereo={"T_cam2_cam1": "identity"}), "4x4 matrix of numbers"),
    "dot-dot cloud": (lambda d: d["captures"][0].update(cloud="../outside.ply"), "leaves the session folder"),
    "nested dot-dot": (lambda d: d["captures"][0].update(cloud="clouds/../../x.ply"), "leaves the session folder"),
    "absolute image": (lambda d: d["captures"][0]["images"].update(cam1="/etc/passwd"), "absolute path"),
    "windows path": (lambda d: d["captures"][0].update(cloud="C:\\data\\p01.ply"), "absolute path"),
    "unc path": (lambda d: d["captures"][0].update(cloud="\\\\server\\share\\p01.ply"), "absolute path"),
    "nul in path": (lambda d: d["captures"][0].update(cloud="clouds/p01\x00.ply"), "NUL"),
    "empty path": (lambda d: d["captures"][0].update(cloud=""), "expected a relative path"),
    "absolute intrinsics": (lambda d: d["cameras"]["cam1"].update(intrinsics="/tmp/cam1.yaml"), "absolute path"),
    "capture id with slash": (lambda d: d["captures"][0].update(id="../p01"), "is not allowed"),
    "camera name with slash": (lambda d: d["cameras"].update({"a/b": {"intrinsics": "intrinsics/cam1.yaml"}}), "is not allowed"),
    "background escapes": (lambda d: d["cameras"]["cam1"].update(background="../../bg"), "leaves the session folder"),
}


@pytest.mark.parametrize("case", list(BAD_EDITS))
def test_structural_errors_name_the_manifest(make_session, tmp_path, case):
    fn, match = BAD_EDITS[case]
    root = make_session(tmp_path, n_captures=2)
    edit_manifest(root, fn)
    with pytest.raises(SessionError, match=match) as ei:
        load_session(root)
    assert ei.value.path == root.resolve() / "session.yaml"
    assert len(str(ei.value)) < 400


@pytest.mark.parametrize("content,match", [
    (b"", "expected a YAML mapping"), (b"- a\n- b\n", "expected a YAML mapping"),
    (b"sphere: {diameter: 0.22\n", "invalid YAML at line"), (b"\xff\xfe\x00\x01", "invalid UTF-8"),
    (b"[" * 10000, "invalid YAML"), (b"a: &x [1]\nb: *y\n", "invalid YAML"), (b"!!python/object:os.system {}", "invalid YAML"),
])
def test_unreadable_manifests(tmp_path, content, match):
    (tmp_path / "session.yaml").write_bytes(content)
    with pytest.raises(SessionError, match=match) as ei:
        load_session(tmp_path)
    assert ei.value.path.name == "session.yaml"


def test_missing_folder_and_manifest(tmp_path):
    with pytest.raises(SessionError, match="session folder not found"):
        load_session(tmp_path / "nope")
    with pytest.raises(SessionError, match="not found"):
        load_session(tmp_path)
    (tmp_path / "file.txt").write_text("x")
    with pytest.raises(SessionError, match="not a folder"):
        load_session(tmp_path / "file.txt")
    (tmp_path / "s2" / "session.yaml").mkdir(parents=True)
    with pytest.raises(SessionError, match="not a regular file"):
        load_session(tmp_path / "s2")


def test_symlinks_outside_are_refused_inside_are_fine(make_session, tmp_path):
    root = make_session(tmp_path, n_captures=2)
    outside = tmp_path / "outside.ply"
    outside.write_bytes((root / "clouds" / "p01.ply").read_bytes())
    os.symlink(outside, root / "clouds" / "link.ply")
    os.symlink(root / "clouds" / "p02.ply", root / "clouds" / "inner.ply")
    os.symlink(tmp_path, root / "up")  # a symlinked folder leading out
    manifest = root / "session.yaml"
    with pytest.raises(SessionError, match="leaves the session folder"):
        resolve_inside(root, "clouds/link.ply", manifest, "cloud")
    with pytest.raises(SessionError, match="leaves the session folder"):
        resolve_inside(root, "up/outside.ply", manifest, "cloud")
    assert resolve_inside(root, "clouds/inner.ply", manifest, "cloud") == (root / "clouds" / "p02.ply").resolve()
    os.symlink("loop_a", root / "loop_b")
    os.symlink("loop_b", root / "loop_a")
    with pytest.raises(SessionError):
        resolve_inside(root, "loop_a", manifest, "cloud")
    edit_manifest(root, lambda d: d["captures"][0].update(cloud="clouds/link.ply"))
    with pytest.raises(SessionError, match="capture p01 cloud: path 'clouds/link.ply' leaves"):
        load_session(root)


def test_session_folder_itself_may_be_a_symlink(make_session, tmp_path):
    root = make_session(tmp_path, n_captures=2)
    os.symlink(root, tmp_path / "alias")
    s = load_session(tmp_path / "alias")
    assert s.root == root.resolve() and s.captures[0].cloud_path.is_file()


def test_parse_transform():
    T = np.eye(4)
    T[:3, 3] = [1, 2, 3]
    np.testing.assert_array_equal(parse_transform(None, T.tolist(), "T"), T)
    mirror = np.diag([1.0, 1.0, -1.0, 1.0])
    for bad in (mirror.tolist(), [[1, 2], [3]], [[float("inf")] * 4] * 4, None, {"a": 1}):
        with pytest.raises(SessionError):
            parse_transform(None, bad, "T")


def test_validate_clean_session_has_no_problems(make_session, tmp_path):
    root = make_session(tmp_path, n_captures=3, cameras=("cam1", "cam2"), background=True, detections=True)
    check = validate_session(root)
    assert check.problems == []
    assert check.cloud_points == {"p01": 300, "p02": 300, "p03": 300}
    assert set(check.cameras) == {"cam1", "cam2"}


def test_validate_lists_every_problem_at_once(make_session, tmp_path):
    root = make_session(tmp_path, n_captures=4, cameras=("cam1", "cam2"), background=True)
    (root / "clouds" / "p01.ply").unlink()  # missing
    (root / "clouds" / "p02.ply").write_bytes((root / "clouds" / "p02.ply").read_bytes()[:300])  # truncated
    (root / "images" / "cam1" / "p03.png").write_bytes(b"not a png")  # corrupt
    import cv2

    cv2.imwrite(str(root / "images" / "cam2" / "p04.png"), np.zeros((10, 20, 3), np.uint8))  # wrong size
    (root / "intrinsics" / "cam2.yaml").write_text("image_width: 64\n")  # incomplete; cam2 sizes unchecked
    (root / "backgrounds" / "cam1" / "bg0.png").write_bytes(b"")
    (root / "detections.yaml").write_text("captures: {p77: {}}\n")
    check = validate_session(root)
    msgs = [str(e) for e in check.problems]
    expect = [("p01.ply", "not found"), ("p02.ply", "truncated"), ("p03.png", "cannot decode"),
              ("cam2.yaml", "missing 'image_height'"), ("bg0.png", "empty"), ("detections.yaml", "p77")]
    for name, what in expect:
        assert any(name in m and what in m for m in msgs), (name, what, msgs)
    assert len(check.problems) == len(expect)
    assert check.cloud_points == {"p03": 300, "p04": 300}


def test_validate_image_size_mismatch(make_session, tmp_path):
    root = make_session(tmp_path, n_captures=2)
    import cv2

    cv2.imwrite(str(root / "images" / "cam1" / "p02.png"), np.zeros((48, 65, 3), np.uint8))
    check = validate_session(root)
    assert len(check.problems) == 1
    e = check.problems[0]
    assert e.path.name == "p02.png" and "65 x 48 but its intrinsics say 64 x 48" in e.problem


def test_validate_unusable_manifest_gives_one_problem(tmp_path):
    (tmp_path / "session.yaml").write_text("sphere: {diameter: -1}\n")
    check = validate_session(tmp_path)
    assert check.session is None and len(check.problems) == 1


def test_yaml11_exponent_strings_are_numbers(make_session, tmp_path):
    # YAML 1.1 (PyYAML) reads 22e-2 without a dot as a string: accept it as a number
    root = make_session(tmp_path, n_captures=2)
    text = (root / "session.yaml").read_text().replace("diameter: 0.22", "diameter: 22e-2")
    (root / "session.yaml").write_text(text)
    assert load_session(root).sphere_diameter_m == pytest.approx(0.22)
