"""app/state.py and app/uploads.py: change records, undo, concurrent edits, safe uploads (no viser)."""

from __future__ import annotations

import io
import stat
import threading
import zipfile
from pathlib import Path

import numpy as np
import pytest
import yaml

from app.state import WorkbenchState
from app.uploads import safe_unpack_zip
from calib_core.camera import CameraModel
from calib_core.detections import load_detections
from calib_core.errors import SessionError
from calib_core.io.images import save_image
from calib_core.io.intrinsics import save_intrinsics_ros
from calib_core.session import load_session


def make_session(root: Path, n_captures: int = 3) -> Path:
    """A tiny, valid session: one camera (64x48), blank images, small .npy clouds."""
    root.mkdir(parents=True, exist_ok=True)
    cam = CameraModel(64, 48, [[50, 0, 31.5], [0, 50, 23.5], [0, 0, 1]], name="cam1")
    save_intrinsics_ros(root / "intrinsics" / "cam1.yaml", cam, "cam1")
    rng = np.random.default_rng(0)
    caps = []
    for i in range(n_captures):
        cid = f"p{i + 1:02d}"
        save_image(root / "images" / f"{cid}.png", np.full((48, 64, 3), 30 * i, np.uint8))
        (root / "clouds").mkdir(exist_ok=True)
        np.save(root / "clouds" / f"{cid}.npy", rng.normal(size=(50, 3)) + [0, 0, 3])
        caps.append({"id": cid, "cloud": f"clouds/{cid}.npy", "images": {"cam1": f"images/{cid}.png"}})
    manifest = {"format": "sonar-camera-session/1", "name": "tiny", "sphere": {"diameter": 0.22},
                "cameras": {"cam1": {"intrinsics": "intrinsics/cam1.yaml"}}, "captures": caps}
    (root / "session.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False))
    dets = {"format": "sonar-camera-detections/1", "captures": {
        c["id"]: {"sonar": {"status": "auto", "center": [0.1 * k, 0.0, 3.0], "score": 0.9},
                  "cam1": {"status": "auto", "center": [30.0 + k, 20.0], "score": 0.8}} for k, c in enumerate(caps)}}
    (root / "detections.yaml").write_text(yaml.safe_dump(dets, sort_keys=False))
    return root


@pytest.fixture()
def state(tmp_path):
    st = WorkbenchState()
    st.open(make_session(tmp_path / "s"))
    return st


def on_disk(st):
    return load_detections(load_session(st.session.root))


def test_reject_saves_at_once_with_a_change_record(state):
    state.set_status("p02", "rejected", "browser-1")
    disk = on_disk(state)
    assert disk["p02"]["sonar"]["status"] == "rejected" and disk["p02"]["cam1"]["status"] == "rejected"
    rec = disk["p02"]["cam1"]["history"][-1]
    assert rec["status"] == "rejected" and rec["client"] == "browser-1" and rec["action"] == "reject"
    assert rec["center"] == [31.0, 20.0] and "T" in rec["time"]
    assert disk["p01"]["cam1"]["status"] == "auto"  # other captures untouched
    assert disk == state.detections


def test_correct_then_undo_restores_and_records(state):
    state.correct("p01", "cam1", {"center": [12.5, 7.25], "method": "operator-click"}, "browser-7")
    assert on_disk(state)["p01"]["cam1"]["center"] == [12.5, 7.25]
    assert on_disk(state)["p01"]["cam1"]["status"] == "corrected"
    state.undo("browser-7")
    e = on_disk(state)["p01"]["cam1"]
    assert e["status"] == "auto" and e["center"] == [30.0, 20.0]
    assert [h["action"] for h in e["history"]] == ["correct", "undo correct"]
    assert [h["kind"] for h in e["history"]] == ["do", "undo"]
    with pytest.raises(SessionError, match="nothing to undo"):
        state.undo("browser-7")


def test_undo_is_shared_by_clients_and_refuses_a_hand_edit(state):
    state.set_status("p01", "accepted", "browser-1", ["cam1"])
    state.correct("p01", "cam1", {"center": [1.0, 2.0]}, "browser-2")
    state.undo("browser-3")  # any client undoes the session's latest change
    assert on_disk(state)["p01"]["cam1"]["status"] == "accepted"
    state.undo("browser-1")
    assert on_disk(state)["p01"]["cam1"]["status"] == "auto"
    with pytest.raises(SessionError, match="nothing to undo"):
        state.undo("browser-1")
    state.correct("p02", "cam1", {"center": [3.0, 4.0]}, "b")
    path = state.session.root / "detections.yaml"
    doc = yaml.safe_load(path.read_text())
    doc["captures"]["p02"]["cam1"]["center"] = [9.0, 9.0]  # a hand edit after the change
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(SessionError, match="changed since"):
        state.undo("b")


def test_undo_redo_survive_a_restart_and_a_new_change_clears_redo(state):
    root = state.session.root
    state.correct("p01", "cam1", {"center": [12.5, 7.25]}, "browser-1")
    state.set_status("p02", "rejected", "browser-1")
    fresh = WorkbenchState()  # another process, later (a reload or a restart)
    fresh.open(root)
    ch = fresh.undo("browser-9")
    assert ch.action == "reject" and {(c, s) for c, s, _p, _n in ch.items} == {("p02", "sonar"), ("p02", "cam1")}
    assert on_disk(fresh)["p02"]["cam1"]["status"] == "auto"
    fresh.undo("browser-9")
    assert on_disk(fresh)["p01"]["cam1"]["center"] == [30.0, 20.0]
    again = WorkbenchState()
    again.open(root)
    assert again.redo("browser-2").action == "correct"
    e = on_disk(again)["p01"]["cam1"]
    assert e["status"] == "corrected" and e["center"] == [12.5, 7.25]
    assert [h["kind"] for h in e["history"]] == ["do", "undo", "redo"]
    again.undo("x")
    again.redo("x")
    assert on_disk(again)["p01"]["cam1"]["center"] == [12.5, 7.25]
    again.set_status("p03", "rejected", "x")  # a new change: the reject of p02 can no longer be redone
    with pytest.raises(SessionError, match="nothing to redo"):
        again.redo("x")
    assert on_disk(again)["p02"]["cam1"]["status"] == "auto"


def test_undo_of_a_first_entry_asks_for_detection_again(tmp_path):
    root = make_session(tmp_path / "s")
    (root / "detections.yaml").unlink()
    st = WorkbenchState()
    st.open(root)
    st.correct("p01", "cam1", {"center": [5.0, 6.0]}, "b")
    assert "p01" in st.missing()  # sonar not detected yet
    st.undo("b")
    assert on_disk(st)["p01"]["cam1"].get("center") is None and "p01" in st.missing()
    st.redo("b")
    assert on_disk(st)["p01"]["cam1"]["center"] == [5.0, 6.0]


def test_accept_needs_a_centre_and_unknown_sensor_is_refused(state):
    state.correct("p03", "cam1", {"center": [5.0, 5.0]}, "b")
    with pytest.raises(SessionError, match="no sensor"):
        state.apply([("p01", "cam9", {"status": "accepted", "center": [1, 2]})], "b", "x")
    state.apply([("p02", "cam1", {"status": "auto", "reason": "no sphere"})], "b", "x")
    with pytest.raises(SessionError, match="nothing to accept"):
        state.set_status("p02", "accepted", "b", ["cam1"])


def test_external_edit_is_picked_up_before_a_change(state):
    other = WorkbenchState()
    other.open(state.session.root)
    other.set_status("p03", "rejected", "cli")
    state.set_status("p01", "accepted", "browser-1")
    disk = on_disk(state)
    assert disk["p03"]["sonar"]["status"] == "rejected"  # not lost by the second writer
    assert disk["p01"]["sonar"]["status"] == "accepted"


@pytest.mark.parametrize("two_servers", [False, True])
def test_concurrent_edits_of_one_capture_end_consistent(state, two_servers):
    states = [state]
    if two_servers:
        s2 = WorkbenchState()
        s2.open(state.session.root)
        states.append(s2)
    n_threads, n_ops = 6, 15
    errors, made = [], []

    def worker(k):
        st = states[k % len(states)]
        try:
            for i in range(n_ops):
                if i % 3 == 0:
                    made.append(st.set_status("p01", "accepted" if (i // 3) % 2 == 0 else "rejected", f"c{k}", ["cam1"]))
                else:
                    made.append(st.correct("p01", "cam1", {"center": [float(k), float(i)]}, f"c{k}"))
        except SessionError as e:  # "already accepted" races are legitimate refusals
            if "already" not in str(e):
                errors.append(e)

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(n_threads)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    disk = on_disk(state)
    hist = disk["p01"]["cam1"]["history"]
    assert len(hist) == len(made)  # every change recorded once, none lost
    assert sorted(h["change"] for h in hist) == sorted({ch.id for ch in made})  # numbered uniquely
    last = hist[-1]
    assert disk["p01"]["cam1"]["status"] == last["status"]
    if last["status"] == "corrected":
        assert disk["p01"]["cam1"]["center"] == last["center"]
    for st in states:  # each server sees the file after its next sync
        st.set_status("p02", "rejected", "z") if st is states[0] else None
    assert on_disk(state)["p02"]["cam1"]["status"] == "rejected"


def test_merge_automatic_keeps_operator_entries(state):
    state.set_status("p01", "rejected", "b")
    state.merge_automatic({"p01": {"cam1": {"status": "auto", "center": [9.0, 9.0]}},
                           "p02": {"cam1": {"status": "auto", "center": [8.0, 8.0]}}})
    disk = on_disk(state)
    assert disk["p01"]["cam1"]["status"] == "rejected" and disk["p02"]["cam1"]["center"] == [8.0, 8.0]


def test_open_by_path_respects_allowed_roots(tmp_path):
    sess = make_session(tmp_path / "inside" / "s")
    other = make_session(tmp_path / "outside" / "s")
    st = WorkbenchState(allowed_roots=[tmp_path / "inside"])
    st.open(sess, check_root=True)
    with pytest.raises(SessionError, match="outside the folders"):
        st.open(other, check_root=True)
    with pytest.raises(SessionError):
        st.open(tmp_path / "inside" / "../outside/s", check_root=True)
    assert st.session.root == sess.resolve()


# ---- uploads -----------------------------------------------------------------
def zip_of(entries: dict[str, bytes], symlink: str | None = None) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for name, data in entries.items():
            zf.writestr(name, data)
        if symlink:
            info = zipfile.ZipInfo(symlink)
            info.external_attr = (stat.S_IFLNK | 0o777) << 16
            zf.writestr(info, "/etc/passwd")
    return buf.getvalue()


def session_zip(tmp_path, prefix="mysession/") -> bytes:
    src = make_session(tmp_path / "src")
    return zip_of({prefix + str(p.relative_to(src)): p.read_bytes() for p in src.rglob("*") if p.is_file()})


def test_upload_valid_zip_unpacks_and_loads(tmp_path):
    root = safe_unpack_zip(session_zip(tmp_path), tmp_path / "uploads")
    assert (tmp_path / "uploads").resolve() in root.parents
    assert load_session(root).name == "tiny"


@pytest.mark.parametrize("bad,match", [
    ({"../evil.txt": b"x"}, r"\.\."),
    ({"a/../../evil.txt": b"x"}, r"\.\."),
    ({"/etc/evil.txt": b"x"}, "absolute"),
    ({"C:/evil.txt": b"x"}, "absolute"),
    ({"notes.txt": b"x"}, "no session.yaml"),
])
def test_upload_refuses_unsafe_archives(tmp_path, bad, match):
    with pytest.raises(SessionError, match=match):
        safe_unpack_zip(zip_of(bad), tmp_path / "uploads")
    assert not (tmp_path / "evil.txt").exists()
    assert not list((tmp_path / "uploads").glob("*"))  # nothing left behind


def test_upload_refuses_symlinks_bombs_and_oversize(tmp_path):
    with pytest.raises(SessionError, match="symlink"):
        safe_unpack_zip(zip_of({"s/session.yaml": b"x"}, symlink="s/link"), tmp_path / "u")
    bomb = zip_of({"s/session.yaml": b"a: 1\n", "s/big.bin": b"\0" * 2_000_000})
    with pytest.raises(SessionError, match="unpacks to more than"):
        safe_unpack_zip(bomb, tmp_path / "u", max_unpacked_bytes=1_000_000)
    with pytest.raises(SessionError, match="limit"):
        safe_unpack_zip(bomb, tmp_path / "u", max_upload_bytes=1000)
    with pytest.raises(SessionError, match="not a zip"):
        safe_unpack_zip(b"PK\x03\x04 garbage", tmp_path / "u")


def test_results_for_a_session_no_longer_open_are_discarded(tmp_path):
    a, b = make_session(tmp_path / "a"), make_session(tmp_path / "b")
    st = WorkbenchState()
    st.open(a)
    session_a, _dets, _cal = st.snapshot()  # what a worker thread took when it started
    st.open(b)
    before = (b / "detections.yaml").read_bytes()
    with pytest.raises(SessionError, match="another session was opened"):
        st.merge_automatic({"p01": {"cam1": {"status": "auto", "center": [1.0, 1.0]}}}, session=session_a)
    with pytest.raises(SessionError, match="another session was opened"):
        st.set_calibration({"format": "sonar-camera-calibration/1", "cameras": {}}, session=session_a)
    assert (b / "detections.yaml").read_bytes() == before
    assert not (b / "results").exists() and not (a / "results").exists()
