"""calib_core.io.atomic: content, permissions, failure leaves the old file, stale temp sweep."""

from __future__ import annotations

import json
import os
import stat
import time

import pytest
import yaml

from calib_core.io import atomic
from calib_core.io.atomic import atomic_write_bytes, atomic_write_json, atomic_write_text, atomic_write_yaml


def test_writes_and_replaces(tmp_path):
    p = tmp_path / "sub" / "f.bin"
    atomic_write_bytes(p, b"one")
    atomic_write_bytes(p, b"two")
    assert p.read_bytes() == b"two"
    assert os.listdir(p.parent) == ["f.bin"]
    atomic_write_text(tmp_path / "t.txt", "héllo")
    assert (tmp_path / "t.txt").read_text(encoding="utf-8") == "héllo"
    atomic_write_yaml(tmp_path / "y.yaml", {"a": [1, 2], "b": {"c": "d"}})
    assert yaml.safe_load((tmp_path / "y.yaml").read_text()) == {"a": [1, 2], "b": {"c": "d"}}
    atomic_write_json(tmp_path / "j.json", {"x": 1.5})
    assert json.loads((tmp_path / "j.json").read_text()) == {"x": 1.5}


def test_new_files_get_normal_permissions_and_old_modes_are_kept(tmp_path):
    p = tmp_path / "f.yaml"
    atomic_write_text(p, "a")
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(p.stat().st_mode) == 0o666 & ~umask, "not mkstemp's 0600"
    os.chmod(p, 0o640)
    atomic_write_text(p, "b")
    assert stat.S_IMODE(p.stat().st_mode) == 0o640


def test_failed_write_keeps_the_old_file_and_leaves_no_temp(tmp_path):
    p = tmp_path / "d.yaml"
    atomic_write_yaml(p, {"v": 1})
    with pytest.raises(yaml.representer.RepresenterError):
        atomic_write_yaml(p, {"v": object()})  # fails before touching the disk
    with pytest.raises(TypeError):
        atomic_write_bytes(p, "not bytes")  # fails inside the temp-file write
    assert yaml.safe_load(p.read_text()) == {"v": 1}
    assert os.listdir(tmp_path) == ["d.yaml"]


def test_replacing_a_symlink_replaces_the_link_not_its_target(tmp_path):
    outside = tmp_path / "outside.txt"
    outside.write_text("keep me")
    (tmp_path / "s").mkdir()
    os.symlink(outside, tmp_path / "s" / "f.txt")
    atomic_write_text(tmp_path / "s" / "f.txt", "new")
    assert outside.read_text() == "keep me"
    assert not (tmp_path / "s" / "f.txt").is_symlink() and (tmp_path / "s" / "f.txt").read_text() == "new"


def test_stale_temp_files_are_swept_fresh_ones_kept(tmp_path):
    p = tmp_path / "detections.yaml"
    old_tmp = tmp_path / ".detections.yaml.abc123.tmp"
    fresh_tmp = tmp_path / ".detections.yaml.def456.tmp"
    other = tmp_path / ".other.yaml.xyz.tmp"
    for f in (old_tmp, fresh_tmp, other):
        f.write_text("partial")
    past = time.time() - atomic.STALE_TEMP_S - 60
    os.utime(old_tmp, (past, past))
    os.utime(other, (past, past))
    atomic_write_text(p, "x")
    assert not old_tmp.exists(), "a killed writer's leftover is removed"
    assert fresh_tmp.exists(), "a temp file that may belong to a writer still running is kept"
    assert other.exists(), "only temp files of the same target are touched"
