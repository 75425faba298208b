"""Kalibr camchain YAML as an intrinsics file: radtan, equidistant, several cameras, refusals."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from calib_core.camera import CameraModel
from calib_core.errors import SessionError
from calib_core.export import to_kalibr
from calib_core.io.intrinsics import load_intrinsics

CHAIN = {
    "cam0": {"camera_model": "pinhole", "intrinsics": [1100.5, 1101.0, 640.2, 511.7],
             "distortion_model": "radtan", "distortion_coeffs": [-0.21, 0.08, 0.0004, -0.0002],
             "resolution": [1280, 1024], "rostopic": "/left/image_raw"},
    "cam1": {"camera_model": "pinhole", "intrinsics": [460.0, 461.0, 480.0, 300.0],
             "distortion_model": "equidistant", "distortion_coeffs": [0.05, -0.02, 0.003, -0.0005],
             "resolution": [960, 600], "rostopic": "/right/image_raw",
             "T_cn_cnm1": np.eye(4).tolist()},
}


def _write(tmp_path, data, name="camchain.yaml"):
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data))
    return p


def test_entry_by_key_and_by_rostopic(tmp_path):
    p = _write(tmp_path, CHAIN)
    left = load_intrinsics(p, "cam2", entry="cam0")
    assert not left.fisheye and (left.width_px, left.height_px) == (1280, 1024)
    assert np.allclose(left.dist, [-0.21, 0.08, 0.0004, -0.0002, 0.0])
    assert left.fx == 1100.5 and left.cy == 511.7
    right = load_intrinsics(p, "right")  # the session names its camera like the topic
    assert right.fisheye and np.allclose(right.dist, [0.05, -0.02, 0.003, -0.0005])


def test_several_cameras_and_no_name_matching_is_refused(tmp_path):
    """A session camera called cam1 is NOT Kalibr's cam1 (Kalibr counts from cam0)."""
    p = _write(tmp_path, CHAIN)
    with pytest.raises(SessionError, match=r"holds 2 cameras .*cam0.*cam1.*'cam1'.*intrinsics_entry"):
        load_intrinsics(p, "cam1")
    with pytest.raises(SessionError, match=r"no entry 'cam5' \(it holds 'cam0', 'cam1'\)"):
        load_intrinsics(p, "cam1", entry="cam5")


def test_session_names_the_entry(tmp_path):
    from calib_core.session import load_session

    (tmp_path / "calib").mkdir()
    _write(tmp_path / "calib", CHAIN)
    (tmp_path / "session.yaml").write_text(yaml.safe_dump({
        "format": "sonar-camera-session/1", "name": "k", "sphere": {"diameter": 0.3},
        "cameras": {"cam1": {"intrinsics": "calib/camchain.yaml", "intrinsics_entry": "cam0"},
                    "cam2": {"intrinsics": "calib/camchain.yaml", "intrinsics_entry": "cam1"}},
        "captures": [{"id": "p01", "cloud": "c.ply", "images": {"cam1": "a.png", "cam2": "b.png"}}]}))
    s = load_session(tmp_path)
    assert s.camera_model("cam1").width_px == 1280 and s.camera_model("cam2").fisheye


def test_one_camera_chain_needs_no_name(tmp_path):
    cam = load_intrinsics(_write(tmp_path, {"cam0": CHAIN["cam1"]}))
    assert cam.fisheye and cam.width_px == 960


@pytest.mark.parametrize("change,match", [
    (dict(camera_model="omni"), "camera_model 'omni' is not supported"),
    (dict(distortion_model="fov"), "distortion_model 'fov' is not supported"),
    (dict(intrinsics=[1.0, 2.0, 3.0]), "'intrinsics' has 3 values, expected 4"),
    (dict(distortion_coeffs=[0.1, float("nan"), 0, 0]), "NaN"),
    (dict(resolution=[0, 600]), "not plausible"),
    (dict(intrinsics=[-5.0, 460.0, 480.0, 300.0]), "focal lengths must be positive"),
    (dict(distortion_model="none"), "distortion_model 'none' but distortion_coeffs are not zero"),
    (dict(distortion_model="none", distortion_coeffs="x"), "must be a list of numbers"),
    (dict(distortion_model="none", distortion_coeffs=0.1), "must be a list of numbers"),
])
def test_bad_entries_are_refused_in_one_line(tmp_path, change, match):
    p = _write(tmp_path, {"cam0": {**CHAIN["cam1"], **change}})
    with pytest.raises(SessionError, match=match) as e:
        load_intrinsics(p)
    assert str(p) in str(e.value) and "\n" not in str(e.value)


def test_round_trip_through_kalibr_export(tmp_path):
    K = [[900.0, 0, 955.0], [0, 901.0, 540.0], [0, 0, 1]]
    models = {"cam1": CameraModel(1920, 1080, K, [-0.1, 0.02, 0.001, 0.0005, 0.0]),
              "cam2": CameraModel(1920, 1080, K, [0.04, -0.01, 0.002, -0.0003], fisheye=True)}
    calib = {"cameras": {c: {"T_cam_sonar": np.eye(4).tolist()} for c in models}}
    p = tmp_path / "chain.yaml"
    p.write_text(to_kalibr(calib, models))
    for name, m in models.items():
        back = load_intrinsics(p, name)  # matched by camera_name
        assert back.fisheye == m.fisheye and np.allclose(back.dist, m.dist) and np.allclose(back.K, m.K)


@pytest.mark.parametrize("value", [["radtan"], {"a": 1}])
def test_distortion_model_of_the_wrong_type_is_one_line(tmp_path, value):
    """A list or mapping as distortion_model is unhashable: it must not escape as a TypeError."""
    p = _write(tmp_path, {"cam0": {**CHAIN["cam0"], "distortion_model": value}})
    with pytest.raises(SessionError, match="distortion_model .* is not supported"):
        load_intrinsics(p)


def test_two_entries_naming_the_camera_are_refused_not_guessed(tmp_path):
    """Two entries with the same camera_name (or a name matching one's rostopic and the other's
    camera_name): taking the first would silently calibrate with a guessed camera."""
    chain = {"cam0": {**CHAIN["cam0"], "camera_name": "left"},
             "cam1": {**CHAIN["cam1"], "camera_name": "left"}}
    p = _write(tmp_path, chain)
    with pytest.raises(SessionError, match=r"2 entries .*'cam0', 'cam1'.*'left'.*intrinsics_entry"):
        load_intrinsics(p, "left")
    assert load_intrinsics(p, "left", entry="cam1").fisheye
    chain = {"cam0": {**CHAIN["cam0"], "rostopic": "/right/image_raw"}, "cam1": CHAIN["cam1"]}
    with pytest.raises(SessionError, match="2 entries"):
        load_intrinsics(_write(tmp_path, chain, "b.yaml"), "right")


def test_no_camera_name_message_and_odd_names(tmp_path):
    p = _write(tmp_path, CHAIN)
    with pytest.raises(SessionError, match="holds 2 cameras") as e:
        load_intrinsics(p)
    assert "None" not in str(e.value)
    one = {"cam0": {**CHAIN["cam1"], "camera_name": "a\nb\x1b[31m"}}
    assert "\n" not in load_intrinsics(_write(tmp_path, one, "c.yaml")).name
    tree = {"cam0": {**CHAIN["cam1"], "camera_name": {"x": [1, 2]}}}
    assert load_intrinsics(_write(tmp_path, tree, "d.yaml")).name == "cam0"


def test_absurd_resolution_is_a_short_message(tmp_path):
    p = _write(tmp_path, {"cam0": {**CHAIN["cam1"], "resolution": [1e300, 600]}})
    with pytest.raises(SessionError, match="not plausible") as e:
        load_intrinsics(p)
    assert len(str(e.value)) < len(str(p)) + 120


def test_the_chosen_entry_is_part_of_an_image_detection_fingerprint(tmp_path):
    """Pointing a camera at another camchain entry changes its intrinsics without changing a file:
    old auto entries must not match."""
    from calib_core import fingerprint as fpm
    from calib_core.pipeline import SessionData, detection_inputs
    from calib_core.session import load_session

    (tmp_path / "calib").mkdir()
    _write(tmp_path / "calib", CHAIN)
    (tmp_path / "a.png").write_bytes(b"x")
    man = {"format": "sonar-camera-session/1", "name": "k", "sphere": {"diameter": 0.3},
           "cameras": {"cam1": {"intrinsics": "calib/camchain.yaml", "intrinsics_entry": "cam0"}},
           "captures": [{"id": "p01", "cloud": "c.ply", "images": {"cam1": "a.png"}}]}
    digests = []
    for entry in ("cam0", "cam1"):
        man["cameras"]["cam1"]["intrinsics_entry"] = entry
        (tmp_path / "session.yaml").write_text(yaml.safe_dump(man))
        paths, params = detection_inputs(SessionData(load_session(tmp_path)), "p01", "cam1")
        digests.append(fpm.fingerprint(tmp_path, paths, params)["digest"])
    assert digests[0] != digests[1]


@pytest.mark.parametrize("value", [5, "", "a\nb", "x" * 65, ["cam0"]])
def test_session_refuses_an_odd_intrinsics_entry(tmp_path, value):
    from calib_core.session import load_session

    (tmp_path / "calib").mkdir()
    _write(tmp_path / "calib", CHAIN)
    (tmp_path / "session.yaml").write_text(yaml.safe_dump({
        "format": "sonar-camera-session/1", "name": "k", "sphere": {"diameter": 0.3},
        "cameras": {"cam1": {"intrinsics": "calib/camchain.yaml", "intrinsics_entry": value}},
        "captures": [{"id": "p01", "cloud": "c.ply", "images": {"cam1": "a.png"}}]}))
    with pytest.raises(SessionError, match="intrinsics_entry must be a short name"):
        load_session(tmp_path)


ODD = [None, True, "x", "", 5, -1, 1e300, float("nan"), [], [1], ["a", "b"], [[1, 2], [3]], {"a": 1},
       [1e308, 1e308, 1, 1], [0.5, 0.5], list(range(200))]


def test_any_odd_field_value_is_a_session_error_or_a_model(tmp_path):
    """Every field of a camchain entry replaced by odd values (wrong types, unhashable, nested,
    huge, NaN): one SessionError line or a CameraModel, never another exception."""
    rng = np.random.default_rng(11)
    fields = ["camera_model", "intrinsics", "distortion_model", "distortion_coeffs", "resolution",
              "camera_name", "rostopic"]
    for k in range(150):
        entry = dict(CHAIN["cam0"])
        for f in rng.choice(fields, size=int(rng.integers(1, 3)), replace=False):
            entry[str(f)] = ODD[int(rng.integers(len(ODD)))]
        p = _write(tmp_path, {"cam0": entry, "cam1": CHAIN["cam1"]}, f"f{k}.yaml")
        for kw in ({"camera": "left"}, {"camera": "right"}, {"entry": "cam0"}, {}):
            try:
                m = load_intrinsics(p, **kw)
            except SessionError as e:
                assert "\n" not in str(e)
            else:
                assert np.isfinite(m.K).all() and m.width_px > 0 and "\n" not in m.name


def test_intrinsics_entry_on_a_ros_file_is_refused(tmp_path):
    p = tmp_path / "cam1.yaml"
    p.write_text(yaml.safe_dump({"image_width": 640, "image_height": 480,
                                 "camera_matrix": {"rows": 3, "cols": 3, "data": [500, 0, 320, 0, 500, 240, 0, 0, 1]}}))
    assert load_intrinsics(p).width_px == 640
    with pytest.raises(SessionError, match="not a Kalibr camchain"):
        load_intrinsics(p, "cam1", entry="cam0")


@pytest.mark.parametrize("coeffs", [None, [], [0.0, 0.0, 0.0, 0.0]])
def test_none_distortion_with_no_or_zero_coefficients_is_a_pinhole(tmp_path, coeffs):
    entry = {**CHAIN["cam0"], "distortion_model": "none"}
    entry.pop("distortion_coeffs")
    if coeffs is not None:
        entry["distortion_coeffs"] = coeffs
    cam = load_intrinsics(_write(tmp_path, {"cam0": entry}))
    assert not cam.fisheye and not np.any(cam.dist) and cam.fx == 1100.5
