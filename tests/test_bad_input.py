"""Malformed input through the CLI (issue 2 item 8, issue 6 item 3).

Each case corrupts one file of a valid session. For every command that reads that kind
of file: exit status 2, one message naming the file and the problem, no traceback, and
every file of the session byte-for-byte unchanged. Commands that do not read the file may
succeed, but must never show a traceback or exit with another status.

Commands still being written by others are skipped while their module is missing.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Callable

import numpy as np
import pytest
from conftest import cli_command_exists, edit_yaml, run_cli, tree_hash

from calib_core.io.clouds import Cloud, save_cloud
from calib_core.results import save_calibration


@dataclass(frozen=True)
class Case:
    corrupt: Callable  # corrupt(root, tmp_path)
    file: str  # file name the message must contain
    phrase: str  # words the message must contain (case-insensitive)
    kind: str  # manifest / intrinsics / image / cloud / detections / calibration


def _edit(root, fn):
    edit_yaml(root / "session.yaml", fn)


def _intr(root, fn):
    edit_yaml(root / "intrinsics" / "cam1.yaml", fn)


def _cut(path, frac):
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * frac)])


def _nan_cloud(root, _):
    pts = np.full((50, 3), np.nan)  # NaN rows are "no return" and dropped; a cloud of nothing else is refused
    pts[9] = [np.inf, 0, 1]
    save_cloud(root / "clouds" / "p02.ply", Cloud(pts))


def _symlink_out(root, tmp_path):
    (tmp_path / "elsewhere.ply").write_bytes((root / "clouds" / "p01.ply").read_bytes())
    (root / "clouds" / "p01.ply").unlink()
    os.symlink(tmp_path / "elsewhere.ply", root / "clouds" / "p01.ply")


def _wrong_size_image(root, _):
    import cv2

    cv2.imwrite(str(root / "images" / "cam1" / "p02.png"), np.full((40, 60, 3), 128, np.uint8))


def _huge_cloud(root, _):
    p = root / "clouds" / "p03.xyz"
    with open(p, "wb") as f:
        f.truncate(3 * 2**30)  # sparse: costs no disk
    _edit(root, lambda d: d["captures"][2].update(cloud="clouds/p03.xyz"))


def _detections(text):
    return lambda root, _: (root / "detections.yaml").write_text(text)


def _calibration(text):
    return lambda root, _: (root / "results" / "calibration.json").write_text(text)


CASES = {
    "missing cloud": Case(lambda r, _: (r / "clouds" / "p01.ply").unlink(), "p01.ply", "not found", "cloud"),
    "truncated binary ply": Case(lambda r, _: _cut(r / "clouds" / "p01.ply", 0.6), "p01.ply", "truncated", "cloud"),
    "random bytes ply": Case(lambda r, _: (r / "clouds" / "p01.ply").write_bytes(os.urandom(4000)), "p01.ply", "not a PLY", "cloud"),
    "empty cloud file": Case(lambda r, _: (r / "clouds" / "p01.ply").write_bytes(b""), "p01.ply", "empty", "cloud"),
    "cloud with 0 points": Case(lambda r, _: (r / "clouds" / "p01.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n"),
        "p01.ply", "no points", "cloud"),
    "nan/inf points only": Case(_nan_cloud, "p02.ply", "holds no return", "cloud"),
    "huge cloud": Case(_huge_cloud, "p03.xyz", "GiB", "cloud"),
    "symlink outside": Case(_symlink_out, "session.yaml", "leaves the session folder", "manifest"),
    "dot-dot path": Case(lambda r, _: _edit(r, lambda d: d["captures"][0].update(cloud="../x.ply")),
                         "session.yaml", "leaves the session folder", "manifest"),
    "absolute path": Case(lambda r, _: _edit(r, lambda d: d["captures"][0]["images"].update(cam1="/etc/hostname")),
                          "session.yaml", "absolute path", "manifest"),
    "invalid session yaml": Case(lambda r, _: (r / "session.yaml").write_text("sphere: {diameter: 0.22\ncameras: ["),
                                 "session.yaml", "invalid YAML", "manifest"),
    "session yaml random bytes": Case(lambda r, _: (r / "session.yaml").write_bytes(b"\x00\xff" + os.urandom(300)),
                                      "session.yaml", "", "manifest"),
    "missing session yaml": Case(lambda r, _: (r / "session.yaml").unlink(), "session.yaml", "not found", "manifest"),
    "negative diameter": Case(lambda r, _: _edit(r, lambda d: d["sphere"].update(diameter=-0.22)),
                              "session.yaml", "sphere.diameter", "manifest"),
    "cameras as list": Case(lambda r, _: _edit(r, lambda d: d.update(cameras=["cam1"])), "session.yaml", "cameras", "manifest"),
    "image path is a number": Case(lambda r, _: _edit(r, lambda d: d["captures"][0]["images"].update(cam1=5)),
                                   "session.yaml", "relative path", "manifest"),
    "camera matrix 8 values": Case(lambda r, _: _intr(r, lambda d: d["camera_matrix"].update(data=[50, 0, 32, 0, 50, 24, 0, 0])),
                                   "cam1.yaml", "8 values", "intrinsics"),
    "distortion 3 values": Case(lambda r, _: _intr(r, lambda d: d["distortion_coefficients"].update(data=[0.1, 0, 0])),
                                "cam1.yaml", "3 values", "intrinsics"),
    "intrinsics invalid yaml": Case(lambda r, _: (r / "intrinsics" / "cam1.yaml").write_text("image_width: [64\n"),
                                    "cam1.yaml", "invalid YAML", "intrinsics"),
    "intrinsics nan": Case(lambda r, _: _intr(r, lambda d: d["camera_matrix"]["data"].__setitem__(0, float("nan"))),
                           "cam1.yaml", "NaN", "intrinsics"),
    "missing intrinsics": Case(lambda r, _: (r / "intrinsics" / "cam1.yaml").unlink(), "cam1.yaml", "not found", "intrinsics"),
    "image size differs": Case(_wrong_size_image, "p02.png", "intrinsics say", "image"),
    "random bytes image": Case(lambda r, _: (r / "images" / "cam1" / "p01.png").write_bytes(os.urandom(2000)),
                               "p01.png", "cannot decode", "image"),
    "truncated png": Case(lambda r, _: _cut(r / "images" / "cam1" / "p01.png", 0.5), "p01.png", "truncated", "image"),
    "missing image": Case(lambda r, _: (r / "images" / "cam1" / "p03.png").unlink(), "p03.png", "not found", "image"),
    "invalid detections yaml": Case(_detections("captures: {p01: [\n"), "detections.yaml", "invalid YAML", "detections"),
    "detections wrong shape": Case(_detections("captures:\n  p01:\n    sonar: {center: [1, 2], status: accepted}\n"),
                                   "detections.yaml", "center must be 3", "detections"),
    "detections unknown capture": Case(_detections("captures:\n  p42:\n    sonar: {status: rejected}\n"),
                                       "detections.yaml", "p42", "detections"),
    "calibration invalid json": Case(_calibration('{"format": "sonar-camera-calibration/1", "cameras": {'),
                                     "calibration.json", "invalid JSON", "calibration"),
    "calibration wrong shape": Case(_calibration('{"format": "sonar-camera-calibration/1", "cameras": {"cam1": {"T_cam_sonar": [[1, 0, 0]]}}}'),
                                    "calibration.json", "4x4", "calibration"),
}

# which kinds of file each command reads (and so must refuse when broken)
COMMANDS = {
    "info": (lambda r: ["info", str(r)], {"manifest", "intrinsics", "image", "cloud", "detections", "calibration"}),
    "detect": (lambda r: ["detect", str(r)], {"manifest", "intrinsics", "image", "cloud", "detections"}),
    "calibrate": (lambda r: ["calibrate", str(r)], {"manifest", "intrinsics", "image", "cloud", "detections"}),
    "export": (lambda r: ["export", str(r), "--format", "json"], {"manifest", "calibration"}),
    "report": (lambda r: ["report", str(r)], {"manifest", "calibration", "detections"}),
    "plan": (lambda r: ["plan", str(r)], {"manifest", "intrinsics", "detections", "calibration"}),
}


def _session(make_session, tmp_path):
    root = make_session(tmp_path, n_captures=3, cameras=("cam1",))
    T = np.eye(4)
    T[:3, 3] = [0.0, 0.1, 0.0]
    save_calibration(root / "results" / "calibration.json",
                     {"format": "sonar-camera-calibration/1", "session": "test-session",
                      "cameras": {"cam1": {"T_cam_sonar": T.tolist(), "rms_reprojection_px": 0.5,
                                           "captures_used": ["p01", "p02", "p03"],
                                           "covariance": (np.eye(6) * 1e-6).tolist()}}})
    return root


def _check_output(out: str, err: str):
    for text in (out, err):
        assert "Traceback" not in text and "internal error" not in text, text[-3000:]


# detect and calibrate rewrite their outputs anyway: only the files they read are tried on them
PAIRS = [(case, cmd) for case in CASES for cmd in COMMANDS
         if cmd not in ("detect", "calibrate") or CASES[case].kind in COMMANDS[cmd][1]]


@pytest.mark.parametrize("case,command", PAIRS)
def test_bad_input(make_session, tmp_path, capsys, command, case):
    if not cli_command_exists(command):
        pytest.skip(f"sonarcal_cli/commands/{command}.py does not exist yet")
    c = CASES[case]
    argv_of, reads = COMMANDS[command]
    root = _session(make_session, tmp_path)
    c.corrupt(root, tmp_path)
    before = tree_hash(root)
    rc = run_cli(argv_of(root))
    out, err = capsys.readouterr()
    _check_output(out, err)
    if c.kind in reads:
        assert rc == 2, f"exit status {rc}\nstdout: {out[-1500:]}\nstderr: {err[-1500:]}"
        lines = [ln for ln in err.splitlines() if c.file in ln and c.phrase.lower() in ln.lower()]
        assert lines, f"no message naming {c.file} with '{c.phrase}':\n{err}"
        assert len(lines) == 1, f"the problem is reported more than once:\n{err}"
    else:
        assert rc in (0, 2), f"exit status {rc}\n{err[-1500:]}"
        if rc == 2:
            assert "error" in err and ("/" in err), err
    if rc != 0 or command in ("info", "export"):
        assert tree_hash(root) == before, "the session was modified"


def test_info_exit_0_writes_nothing(make_session, tmp_path, capsys):
    root = _session(make_session, tmp_path)
    before = tree_hash(root)
    assert run_cli(["info", str(root)]) == 0
    assert tree_hash(root) == before
    assert "no problems found" in capsys.readouterr().out


@pytest.mark.parametrize("command", ["info", "detect", "calibrate", "export", "report", "serve", "plan"])
def test_missing_session_folder(tmp_path, capsys, command):
    if not cli_command_exists(command):
        pytest.skip(f"sonarcal_cli/commands/{command}.py does not exist yet")
    argv = [command, str(tmp_path / "nope")] + (["--format", "json"] if command == "export" else [])
    rc = run_cli(argv)
    out, err = capsys.readouterr()
    _check_output(out, err)
    assert rc == 2 and "nope" in err and "not found" in err
    assert not (tmp_path / "nope").exists(), "nothing created"


def test_usage_errors_exit_2_without_traceback(capsys):
    assert run_cli(["info"]) == 2
    assert run_cli(["no-such-command"]) == 2
    assert run_cli([]) == 2
    out, err = capsys.readouterr()
    _check_output(out, err)
    assert "usage" in err
