"""Fingerprints: reuse of auto detections, session beam width reuse, parallel = sequential.

Entries are compared without their time stamps, fingerprints and timings (keys ending in _ms)."""

from __future__ import annotations

import os

import pytest

from calib_core import fingerprint as fpm
from calib_core.detect import entries
from calib_core.detections import load_detections, save_detections
from calib_core.pipeline import SessionData, detect_session
from calib_core.session import load_session
from calib_core.synth.generate import generate_session


def test_fingerprint_follows_content_params_and_detector(tmp_path):
    f = tmp_path / "a.png"
    f.write_bytes(b"abc" * 100)
    fp = fpm.fingerprint(tmp_path, [f], {"sensor": "image", "d": 0.2})
    entry = {"status": "auto", "fingerprint": fp}
    assert fp["files"]["a.png"].split()[0] == fpm.file_sha256(f)
    assert fpm.matches(entry, tmp_path, [f], {"sensor": "image", "d": 0.2})
    assert not fpm.matches(entry, tmp_path, [f], {"sensor": "image", "d": 0.21})
    assert not fpm.matches(dict(entry, status="accepted"), tmp_path, [f], {"sensor": "image", "d": 0.2})
    st = f.stat()
    f.write_bytes(b"abd" * 100)  # same size; restore the time stamp: only strict mode can tell
    os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert fpm.matches(entry, tmp_path, [f], {"sensor": "image", "d": 0.2})
    assert not fpm.matches(entry, tmp_path, [f], {"sensor": "image", "d": 0.2}, strict=True)
    f.write_bytes(b"abd" * 101)
    assert not fpm.matches(entry, tmp_path, [f], {"sensor": "image", "d": 0.2})
    f.unlink()
    assert not fpm.matches(entry, tmp_path, [f], {"sensor": "image", "d": 0.2})


def _strip(dets):
    return {c: {s: {k: v for k, v in e.items() if k not in ("detected_at", "fingerprint") and not k.endswith("_ms")}
                for s, e in d.items()}
            for c, d in dets.items()}


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    root = generate_session(tmp_path_factory.mktemp("fp") / "s", "quick", seed=7, scale=0.3, pan_step_deg=1.5,
                            n_captures=4)
    session = load_session(root)
    dets = detect_session(SessionData(session), {}, workers=1)
    save_detections(session, dets)
    return root, session, dets


def test_calibrate_reuses_matching_entries_and_redetects_only_changed_ones(small, monkeypatch):
    root, session, dets = small
    ran = []
    real = entries.detect_one
    monkeypatch.setattr(entries, "detect_one", lambda data, cid, sensor, **kw: ran.append((cid, sensor)) or real(data, cid, sensor, **kw))
    again = detect_session(SessionData(session), load_detections(session), workers=1)
    assert ran == [] and again == dets
    cap = session.captures[1]
    cam = next(iter(cap.image_paths))
    st = cap.image_paths[cam].stat()
    os.utime(cap.image_paths[cam], ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))  # touched: rehash, same content
    assert detect_session(SessionData(session), load_detections(session), workers=1) == dets and ran == []
    data = cap.image_paths[cam].read_bytes()
    cap.image_paths[cam].write_bytes(data + b"\0")  # changed content (PNG readers ignore trailing bytes)
    third = detect_session(SessionData(session), load_detections(session), workers=1)
    assert ran == [(cap.id, cam)]
    assert _strip(third) == _strip(dets)  # same pixels: the re-detection reproduces the entry
    cap.image_paths[cam].write_bytes(data)


def test_beam_width_is_adopted_so_redetection_reproduces_entries(small):
    _, session, dets = small
    fresh = detect_session(SessionData(session), load_detections(session), workers=1, reuse=False)
    assert _strip(fresh) == _strip(dets)
    widths = {e["beam_width_deg"] for d in fresh.values() for s, e in d.items() if s == "sonar"}
    assert len(widths) == 1


def test_parallel_detection_equals_sequential(small):
    _, session, dets = small
    par = detect_session(SessionData(session), {}, workers=2)
    assert _strip(par) == _strip(dets)


@pytest.mark.parametrize("rel", ["detect/sonar/detect.py", "io/images.py", "io/clouds.py", "io/intrinsics.py", "camera.py",
                                 "io/kalibr.py", "io/cloud_ascii.py", "io/cloud_binary.py", "io/off.py"])
def test_detector_version_follows_the_loaders_the_inputs_pass_through(tmp_path, rel):
    """A changed loader (16-bit scaling, "no return" points dropped, distortion terms kept)
    changes what the detectors see from the same files: old auto entries must not be reused."""
    import shutil
    from pathlib import Path

    pkg = tmp_path / "calib_core"
    shutil.copytree(Path(fpm.__file__).resolve().parent, pkg, ignore=shutil.ignore_patterns("__pycache__"))
    before = fpm.source_digest(pkg)
    assert fpm.source_digest(pkg) == before
    (pkg / rel).write_text((pkg / rel).read_text() + "\n# changed\n")
    assert fpm.source_digest(pkg) != before
    assert fpm.detector_version().endswith(fpm.source_digest(Path(fpm.__file__).resolve().parent))


def test_the_assumed_stereo_covariance_of_the_vouching_is_in_the_fingerprint():
    """The stereo vouching refuses image detections with the stereo transform's covariance, the
    assumed default when the session states none: a changed default changes detections, so the
    module that defines it must be one of the detector's sources (it was solve/rig.py, not one)."""
    import inspect
    from pathlib import Path

    from calib_core.solve import stereo_cov

    pkg = Path(fpm.__file__).resolve().parent
    covered = {p.resolve() for pattern in fpm.DETECTOR_SOURCES for p in pkg.glob(pattern)}
    for fn in (stereo_cov.default_stereo_cov, stereo_cov.key_stereo_cov, stereo_cov.invert_with_cov):
        assert Path(inspect.getsourcefile(fn)).resolve() in covered, fn.__name__


def test_the_modules_the_detectors_import_are_in_the_fingerprint():
    """The loaders' helpers and the session model decide what a detector sees (a LAS header's
    scale, a confined path): they were outside the fingerprint until it followed the imports."""
    from pathlib import Path

    pkg = Path(fpm.__file__).resolve().parent
    covered = {p.relative_to(pkg).as_posix() for p in fpm.source_files(pkg)}
    for rel in ("io/las_header.py", "io/cloud_headers.py", "geometry.py", "session.py", "detections.py"):
        assert rel in covered, rel
    assert not any(rel.startswith(("app/", "solve/refine")) for rel in covered)


def test_a_module_imported_inside_a_detector_function_changes_the_digest(tmp_path):
    import shutil
    from pathlib import Path

    pkg = tmp_path / "calib_core"
    shutil.copytree(Path(fpm.__file__).resolve().parent, pkg, ignore=shutil.ignore_patterns("__pycache__"))
    (pkg / "helper_x.py").write_text("K = 1\n")
    (pkg / "unrelated_x.py").write_text("K = 1\n")
    det = pkg / "detect" / "image" / "detect.py"
    det.write_text(det.read_text() + "\n\ndef _uses_helper():\n    from calib_core import helper_x\n    return helper_x.K\n")
    before = fpm.source_digest(pkg)
    (pkg / "unrelated_x.py").write_text("K = 2\n")
    assert fpm.source_digest(pkg) == before
    (pkg / "helper_x.py").write_text("K = 2\n")
    assert fpm.source_digest(pkg) != before


def test_a_module_imported_in_a_parenthesised_multiline_import_is_in_the_fingerprint(tmp_path):
    """``from calib_core.x import (\\n    y,\\n)`` (black's style for long imports): both the module
    and a submodule named inside the parentheses are followed (the regex once stopped at the
    line break and dropped the whole import)."""
    pkg = tmp_path / "calib_core"
    (pkg / "detect").mkdir(parents=True)
    (pkg / "util").mkdir()
    (pkg / "util" / "__init__.py").write_text("")
    (pkg / "util" / "helper_y.py").write_text("K = 1\n")
    (pkg / "deep_z.py").write_text("K = 1\n")
    (pkg / "detect" / "x.py").write_text(
        "from calib_core.util import (\n    helper_y,  # a comment\n)\nfrom calib_core.deep_z import (\n    K,\n)\n")
    covered = {p.relative_to(pkg).as_posix() for p in fpm.source_files(pkg)}
    assert {"util/__init__.py", "util/helper_y.py", "deep_z.py"} <= covered
