"""Fingerprints of automatic detections: may an ``auto`` entry be reused as it is?

An ``auto`` entry records ``fingerprint: {digest, detector, files[, hint_uv_px, hint_radius_px]}``:
- ``files``: {path relative to the session: "SHA256 SIZE MTIME_NS"} of every input file
  (image, cloud, intrinsics, background frames), one string each (detections.yaml of a
  100-capture session stays quick to parse);
- ``detector``: the detector's version (sonarcal's version and a digest of the detectors'
  source code and of the loaders their inputs pass through, so any change to either
  invalidates old entries);
- ``digest``: sha256 of the canonical JSON of the file digests and the parameters: the
  detector version, the sphere diameter, the beam width (sonar), the background window
  (image) and a refit hint (a sonar-guided second look), which is recorded with the entry.

:func:`matches` re-derives the digest from the files as they are now and compares. Hashing
every 1080p image and 500k-point cloud again would cost seconds per session, so, like git's
index, a file whose size and modification time (ns) equal the recorded ones is taken to hold
the recorded content; ``strict=True`` rehashes every file.
"""

from __future__ import annotations

import functools
import hashlib
import json
import re
from pathlib import Path

from calib_core import __version__

_CHUNK = 1 << 20


def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


# the files whose code decides an automatic entry besides the detectors (relative to calib_core):
# the loaders the inputs pass through (a changed image scaling, dropped "no return" points or a
# kept distortion term changes what the detectors see from the same file) and the session-level
# second looks, and the stereo vouching between cameras. These are the roots: every calib_core
# module they import (at the top or inside a function) is covered too (:func:`source_files`).
DETECTOR_SOURCES = ("detect/**/*.py", "pipeline.py", "disambiguate/*.py", "stereo/*.py", "solve/stereo_cov.py", "camera.py",
                    "io/images.py", "io/clouds.py", "io/cloud_ascii.py", "io/cloud_binary.py", "io/off.py",
                    "io/intrinsics.py", "io/kalibr.py")

# "from calib_core.a.b import c, d", "from calib_core.a import (\n c,\n)" and "import calib_core.a.b",
# anywhere in a file
_IMPORT = re.compile(r"^[ \t]*(?:from[ \t]+(calib_core(?:\.\w+)*)[ \t]+import[ \t]+(\([^)]*\)|[\w ,\t]+)"
                     r"|import[ \t]+(calib_core(?:\.\w+)*))", re.M)


def _module_file(package_dir: Path, dotted: str) -> Path | None:
    """The file of module ``dotted`` (calib_core.x.y) under ``package_dir``, or None."""
    p = package_dir.joinpath(*dotted.split(".")[1:])
    for f in (p / "__init__.py", p.with_suffix(".py")):
        if f.is_file():
            return f
    return None


def _imported_files(package_dir: Path, f: Path) -> set[Path]:
    """The calib_core files that ``f`` imports (a name imported from a package may be a module)."""
    out = set()
    for m in _IMPORT.finditer(f.read_text(encoding="utf-8")):
        base = m.group(1) or m.group(3)
        names = [n for n in re.findall(r"\w+", re.sub(r"#[^\n]*", "", m.group(2) or "")) if n != "as"]
        for dotted in (base, *(f"{base}.{n}" for n in names)):
            if (g := _module_file(package_dir, dotted)) is not None:
                out.add(g)
    return out


def source_files(package_dir: Path) -> list[Path]:
    """The DETECTOR_SOURCES under ``package_dir`` and every calib_core file they import,
    transitively (read statically, so every shell gets the same list), sorted."""
    seen: set[Path] = set()
    todo = [p for pattern in DETECTOR_SOURCES for p in package_dir.glob(pattern)]
    while todo:
        f = todo.pop()
        if f not in seen:
            seen.add(f)
            todo += _imported_files(package_dir, f) - seen
    return sorted(seen, key=lambda p: p.relative_to(package_dir).as_posix())


def source_digest(package_dir: Path) -> str:
    """Digest of the detectors' source files (:func:`source_files`) under ``package_dir`` (a calib_core folder)."""
    h = hashlib.sha256()
    for p in source_files(package_dir):
        h.update(p.relative_to(package_dir).as_posix().encode())
        h.update(p.read_bytes())
    return h.hexdigest()[:16]


@functools.lru_cache(maxsize=1)
def detector_version() -> str:
    """sonarcal's version and a digest of the detectors' source files (:func:`source_files`)."""
    return f"{__version__}+{source_digest(Path(__file__).resolve().parent)}"


def _files(paths: list[Path]) -> list[Path]:
    """Expand folders (background frame folders) into their files, sorted."""
    out = []
    for p in paths:
        p = Path(p)
        out += sorted(q for q in p.rglob("*") if q.is_file()) if p.is_dir() else [p]
    return out


def _parse(rec) -> tuple[str, int, int] | None:
    """(sha256, size, mtime_ns) of a recorded file, None when malformed."""
    try:
        sha, size, mtime = str(rec).split()
        return sha, int(size), int(mtime)
    except (ValueError, TypeError):
        return None


def _record(path: Path, old, strict: bool) -> str:
    st = path.stat()
    rec = _parse(old) if old is not None else None
    if not strict and rec and rec[1] == st.st_size and rec[2] == st.st_mtime_ns:
        return str(old)
    return f"{file_sha256(path)} {st.st_size} {st.st_mtime_ns}"


def _digest(files: dict, params: dict) -> str:
    blob = json.dumps({"files": {k: v.split()[0] for k, v in sorted(files.items())}, "params": params},
                      sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(blob.encode()).hexdigest()


def _rel(root: Path, p: Path) -> str:
    try:
        return Path(p).resolve().relative_to(Path(root).resolve()).as_posix()
    except ValueError:
        return str(p)


def fingerprint(root: Path, paths: list[Path], params: dict, old: dict | None = None, strict: bool = False) -> dict:
    """The fingerprint of a detection from these input files and parameters. ``old`` (an
    earlier fingerprint) lets unchanged files skip hashing (see the module doc)."""
    prev = (old or {}).get("files") or {}
    files = {}
    for p in _files(paths):
        key = _rel(root, p)
        files[key] = _record(p, prev.get(key), strict)
    params = {"detector": detector_version(), **params}
    out = {"digest": _digest(files, params), "detector": params["detector"], "files": files}
    out.update(_hint(params))
    return out


def matches(entry: dict | None, root: Path, paths: list[Path], params: dict, strict: bool = False) -> bool:
    """Whether ``entry`` is an ``auto`` entry whose recorded fingerprint still matches."""
    fp = (entry or {}).get("fingerprint")
    if not isinstance(fp, dict) or not isinstance(fp.get("files"), dict) or entry.get("status") != "auto":
        return False
    try:
        now = fingerprint(root, paths, dict(params, **_hint(fp)), old=fp, strict=strict)
    except OSError:
        return False
    return now["digest"] == fp.get("digest")


def _hint(d: dict) -> dict:
    """A refit hint (a sonar-guided second look at an image, a seed chosen among sonar candidates)
    is a parameter of that entry, recorded with it."""
    return {k: d[k] for k in ("hint_uv_px", "hint_radius_px", "seed_center_m") if k in d}
