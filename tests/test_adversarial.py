"""Adversarial inputs (issue 14): memory bombs, lying headers, silent corruption, writes
outside the session, script injection, hostile uploads and network clients.

CLI cases run the real entry point in a child process (``tests/adversarial_launch.py``,
under an address-space limit so a bomb fails the test instead of the machine) and assert:
exit status 2, exactly one line on stderr naming the file, no traceback, the child's peak
memory (VmHWM) under 500 MB and its CPU time under 10 s, and nothing changed or created
outside the session (the parent folder is snapshotted). All CLI cases run in parallel in
one module fixture to keep the module fast.
"""

from __future__ import annotations

import io
import os
import socket
import struct
import subprocess
import sys
import time
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Callable

import cv2
import numpy as np
import pytest
from conftest import build_session, edit_yaml, tree_hash

LAUNCHER = Path(__file__).with_name("adversarial_launch.py")
PEAK_LIMIT_KB = 500 * 1024
CPU_LIMIT_S = 10.0


# ---- hostile file builders ----------------------------------------------------------
def billion_laughs(levels: int = 9, width: int = 9) -> str:
    lines = ['l0: &l0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for i in range(1, levels + 1):
        lines.append(f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * width) + "]")
    return "\n".join(lines) + "\n"


def block_laughs() -> str:
    """The same bomb with anchors across keys and block-style lists."""
    out = ["a0: &a0\n" + "".join("  - lol\n" for _ in range(9))]
    for i in range(1, 10):
        out.append(f"a{i}: &a{i}\n" + "".join(f"  - *a{i - 1}\n" for _ in range(9)))
    return "".join(out)


def merge_laughs() -> str:
    """Merge keys (<<) fanning out a mapping tree."""
    out = ["m0: &m0 {" + ", ".join(f"k{j}: lol" for j in range(9)) + "}"]
    for i in range(1, 9):
        out.append(f"m{i}: &m{i} {{" + ", ".join(f"k{j}: *m{i - 1}" for j in range(9)) + "}")
    return "\n".join(out) + "\n"


def _edit_manifest(root: Path, fn) -> None:
    edit_yaml(root / "session.yaml", fn)


def _manifest_with(root: Path, prefix: str, key_line: str) -> None:
    """Prepend YAML text (anchors) and set a top-level key to ``key_line`` (raw YAML)."""
    p = root / "session.yaml"
    text = "\n".join(ln for ln in p.read_text().splitlines() if not ln.startswith("name:"))
    p.write_text(prefix + text + "\n" + key_line + "\n")


def _jpeg_claiming(w: int, h: int) -> bytes:
    ok, buf = cv2.imencode(".jpg", np.full((8, 8, 3), 99, np.uint8))
    data = bytearray(buf.tobytes())
    i = data.find(b"\xff\xc0")
    struct.pack_into(">HH", data, i + 5, h, w)
    return bytes(data)


def _png_claiming(w: int, h: int) -> bytes:
    ok, buf = cv2.imencode(".png", np.full((8, 8, 3), 99, np.uint8))
    data = bytearray(buf.tobytes())
    struct.pack_into(">II", data, 16, w, h)
    struct.pack_into(">I", data, 29, zlib.crc32(bytes(data[12:29])))
    return bytes(data)


def _png16_claiming(w: int, h: int) -> bytes:
    ok, buf = cv2.imencode(".png", np.full((8, 8, 3), 999, np.uint16))
    data = bytearray(buf.tobytes())
    struct.pack_into(">II", data, 16, w, h)
    struct.pack_into(">I", data, 29, zlib.crc32(bytes(data[12:29])))
    return bytes(data)


def _bmp_claiming(w: int, h: int) -> bytes:
    ok, buf = cv2.imencode(".bmp", np.full((8, 8, 3), 99, np.uint8))
    data = bytearray(buf.tobytes())
    struct.pack_into("<ii", data, 18, w, h)
    return bytes(data)


def _tiff_claiming(w: int, h: int) -> bytes:
    entries = [(256, 4, 1, w), (257, 4, 1, h), (258, 3, 1, 8), (259, 3, 1, 1), (262, 3, 1, 1),
               (273, 4, 1, 8), (277, 3, 1, 1), (278, 4, 1, h), (279, 4, 1, 64)]
    ifd = struct.pack("<H", len(entries)) + b"".join(
        struct.pack("<HHI", t, typ, n) + (struct.pack("<HH", v, 0) if typ == 3 else struct.pack("<I", v))
        for t, typ, n, v in entries) + b"\0\0\0\0"
    return b"II*\0" + struct.pack("<I", 8 + 64) + bytes(64) + ifd


def _webp_claiming(w: int, h: int) -> bytes:
    ok, buf = cv2.imencode(".webp", np.full((16, 16, 3), 99, np.uint8), [cv2.IMWRITE_WEBP_QUALITY, 80])
    data = bytearray(buf.tobytes())
    i = data.find(b"\x9d\x01\x2a")
    if i < 0:
        pytest.skip("OpenCV here writes no lossy WebP")
    struct.pack_into("<HH", data, i + 3, w & 0x3FFF, h & 0x3FFF)
    return bytes(data)


def _set_image(root: Path, name: str, data: bytes) -> None:
    (root / "images" / "cam1" / name).write_bytes(data)
    _edit_manifest(root, lambda d: d["captures"][0]["images"].update(cam1=f"images/cam1/{name}"))


def _set_cloud(root: Path, name: str, data: bytes) -> None:
    (root / "clouds" / name).write_bytes(data)
    _edit_manifest(root, lambda d: d["captures"][0].update(cloud=f"clouds/{name}"))


def _las_header(n_points: int, n_vlr: int = 0, offset: int = 227, rec_len: int = 20, fmt: int = 0,
                minor: int = 2) -> bytes:
    h = bytearray(227)
    h[0:4] = b"LASF"
    h[24], h[25] = 1, minor
    struct.pack_into("<HII", h, 94, 227, offset, n_vlr)
    struct.pack_into("<BHI", h, 104, fmt, rec_len, n_points)
    struct.pack_into("<ddd", h, 131, 1e-3, 1e-3, 1e-3)
    return bytes(h) + bytes(4096 - 227)


def _las14_evlr_bomb() -> bytes:
    h = bytearray(375)
    h[0:4], h[24], h[25] = b"LASF", 1, 4
    struct.pack_into("<HII", h, 94, 375, 375, 0)
    struct.pack_into("<BHI", h, 104, 6, 30, 1)
    struct.pack_into("<ddd", h, 131, 1e-3, 1e-3, 1e-3)
    struct.pack_into("<QI", h, 235, 375 + 30, 1)
    struct.pack_into("<Q", h, 247, 1)
    evlr = bytearray(60)
    struct.pack_into("<Q", evlr, 20, 2**62)
    return bytes(h) + bytes(30) + bytes(evlr)


def _npy_claiming(shape) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False, "shape": shape})
    return buf.getvalue() + bytes(240)


def _npy_bytes(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, arr)
    return buf.getvalue()


def _ply_vertex_list(root: Path) -> bytes:
    """p01's points with a list property after x y z whose first row claims 4e9 floats: open3d
    printed an RPly error on stderr and returned one true point and garbage rows (exit 0)."""
    from calib_core.io.clouds import load_cloud

    pts = load_cloud(root / "clouds" / "p01.ply").points_m.astype("<f4")
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(pts)}\nproperty float x\nproperty float y\n"
            "property float z\nproperty list uint float junk\nend_header\n").encode()
    return head + b"".join(p.tobytes() + struct.pack("<I", 4_000_000_000) for p in pts)


def _ply_count_lying_low(root: Path) -> bytes:
    """p01.ply (binary, vertices only) with its vertex count set to 10: 290 points were dropped
    without a word."""
    data = (root / "clouds" / "p01.ply").read_bytes()
    i = data.index(b"element vertex ")
    j = data.index(b"\n", i)
    return data[:i] + b"element vertex 10" + data[j:]


def _las_count_lying_low(root: Path) -> bytes:
    """p01's points written by laspy, the header's point count then set to 10 (of 300)."""
    from calib_core.io.clouds import Cloud, load_cloud, save_cloud

    tmp = root.parent / "outside" / "real.las"
    save_cloud(tmp, Cloud(load_cloud(root / "clouds" / "p01.ply").points_m[:300], None))
    data = bytearray(tmp.read_bytes())
    tmp.unlink()
    struct.pack_into("<I", data, 107, 10)
    return bytes(data)


def _las_scaled(root: Path, scale: float) -> bytes:
    """p01's points written by laspy, the header's three scale factors then set to ``scale``."""
    data = bytearray(_las_count_lying_low(root))
    struct.pack_into("<I", data, 107, 300)
    struct.pack_into("<3d", data, 131, scale, scale, scale)
    return bytes(data)


def _ascii_ply(rows: list[str], n: int | None = None) -> bytes:
    head = (f"ply\nformat ascii 1.0\nelement vertex {len(rows) if n is None else n}\n"
            "property float x\nproperty float y\nproperty float z\nend_header\n")
    return (head + "".join(r + "\n" for r in rows)).encode()


def _good_rows(root: Path) -> list[str]:
    from calib_core.io.clouds import load_cloud

    pts = load_cloud(root / "clouds" / "p01.ply").points_m
    return [f"{x:.6f} {y:.6f} {z:.6f}" for x, y, z in pts]


def _pcd(kind: str, n_declared: int, body: bytes) -> bytes:
    return (f"# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n_declared}\n"
            f"HEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n_declared}\nDATA {kind}\n").encode() + body


def _results_symlink(root: Path, outside: Path) -> None:
    outside.mkdir(exist_ok=True)
    os.symlink(outside, root / "results")


def _detections_with_extra(root: Path, extra: str) -> None:
    (root / "detections.yaml").write_text(
        "format: sonar-camera-detections/1\n" + extra +
        "captures:\n  p01:\n    sonar: {status: rejected}\n")


def _corrupt_background_named_badly(root: Path, _) -> None:
    """A background folder holding a corrupt frame whose file name holds a newline, an OSC
    title escape and a bidi override: the refusal must name it on one line, escaped."""
    bg = root / "backgrounds" / "cam1"
    bg.mkdir(parents=True)
    (bg / "bg0.png").write_bytes((root / "images" / "cam1" / "p01.png").read_bytes())
    (bg / "bg1\x1b]0;owned\x07\u202e\nerror: forged.png").write_bytes(b"not an image")
    _edit_manifest(root, lambda d: d["cameras"]["cam1"].update(background="backgrounds/cam1/"))


def _background_video(root: Path, data: bytes) -> None:
    """cam1's background is a video file holding ``data``: OpenCV's FFmpeg backend printed
    "[mov,mp4,...] moov atom not found" on stderr above our one line."""
    (root / "backgrounds").mkdir()
    (root / "backgrounds" / "bg.mp4").write_bytes(data)
    _edit_manifest(root, lambda d: d["cameras"]["cam1"].update(background="backgrounds/bg.mp4"))


# ---- the CLI cases --------------------------------------------------------------------
@dataclass(frozen=True)
class Case:
    corrupt: Callable  # corrupt(root, outside_dir)
    file: str  # the refusal must name this file
    command: str = "info"
    phrase: str = ""  # and contain this (case-insensitive)


def _p01_ascii_ply_with_text(root, _):
    rows = _good_rows(root)
    rows[len(rows) // 2] = "0.1 abc 0.3"
    (root / "clouds" / "p01.ply").write_bytes(_ascii_ply(rows))


def _p01_ascii_ply_short_row(root, _):
    rows = _good_rows(root)
    rows[5] = "0.1 0.2"
    (root / "clouds" / "p01.ply").write_bytes(_ascii_ply(rows))


CASES: dict[str, Case] = {
    # YAML bombs and deep nesting, in every YAML file
    "alias bomb in session name": Case(lambda r, _: _manifest_with(r, billion_laughs(), "name: *l9"), "session.yaml"),
    "alias bomb, block lists, anchors across keys": Case(
        lambda r, _: _manifest_with(r, block_laughs(), "name: *a9"), "session.yaml"),
    "merge-key bomb": Case(lambda r, _: _manifest_with(r, merge_laughs(), "name: *m8"), "session.yaml"),
    "alias bomb in an unused manifest key": Case(lambda r, _: _manifest_with(r, billion_laughs(), "extra: *l9"),
                                                 "session.yaml"),
    "recursive alias": Case(lambda r, _: _manifest_with(r, "", "name: &x [*x]"), "session.yaml"),
    "nested 50k deep (flow)": Case(lambda r, _: _manifest_with(r, "", "name: " + "[" * 50000 + "]" * 50000),
                                   "session.yaml"),
    "nested 3000 deep (block)": Case(lambda r, _: (r / "session.yaml").write_text(
        "".join("  " * i + "- \n" for i in range(3000)) + "  " * 3000 + "- x\n"), "session.yaml"),
    "nested 50k deep (mappings)": Case(lambda r, _: _manifest_with(r, "", "name: " + "{a: " * 50000 + "1"
                                                                   + "}" * 50000), "session.yaml"),
    "alias bomb in camera_name": Case(lambda r, _: (r / "intrinsics" / "cam1.yaml").write_text(
        billion_laughs() + (r / "intrinsics" / "cam1.yaml").read_text().replace("camera_name: cam1", "camera_name: *l9")),
        "cam1.yaml"),
    "session name with a terminal escape": Case(lambda r, _: _edit_manifest(r, lambda d: d.update(
        name="x\x1b]52;c;ZXZpbA==\x07\nforged line")), "session.yaml", phrase="control characters"),
    "capture id with a newline": Case(lambda r, _: _edit_manifest(r, lambda d: d["captures"][0].update(
        id="p01\nerror: forged")), "session.yaml", phrase="control characters"),
    "camera_name is a tree": Case(lambda r, _: (r / "intrinsics" / "cam1.yaml").write_text(
        (r / "intrinsics" / "cam1.yaml").read_text().replace("camera_name: cam1", "camera_name: {a: [1, 2]}")),
        "cam1.yaml"),
    "deep nesting in intrinsics": Case(lambda r, _: (r / "intrinsics" / "cam1.yaml").write_text(
        "camera_matrix: " + "[" * 50000 + "]" * 50000 + "\n"), "cam1.yaml"),
    "OpenCV YAML intrinsics nested 50k deep": Case(lambda r, _: (r / "intrinsics" / "cam1.yaml").write_text(
        "%YAML:1.0\n---\ncamera_matrix: " + "[" * 50000 + "]" * 50000 + "\n"), "cam1.yaml"),
    "OpenCV YAML intrinsics indented 3000 deep": Case(lambda r, _: (r / "intrinsics" / "cam1.yaml").write_text(
        "%YAML:1.0\n---\n" + "".join(" " * i + f"k{i}:\n" for i in range(3000)) + " " * 3000 + "x: 1\n"), "cam1.yaml"),
    "OpenCV XML intrinsics nested 50k deep": Case(lambda r, _: (r / "intrinsics" / "cam1.yaml").write_text(
        '<?xml version="1.0"?>\n<opencv_storage>' + "<a>" * 50000 + "</a>" * 50000 + "</opencv_storage>\n"),
        "cam1.yaml"),
    "alias bomb in detections extra key (detect)": Case(
        lambda r, _: _detections_with_extra(r, billion_laughs()), "detections.yaml", "detect"),
    "alias bomb in detections (info)": Case(lambda r, _: _detections_with_extra(r, billion_laughs()), "detections.yaml"),
    "detections.yaml with 700 000 values (slow to parse)": Case(lambda r, _: _detections_with_extra(
        r, "x: [" + ", ".join(["1"] * 700_000) + "]\n"), "detections.yaml", "detect"),
    "deep nesting in detections": Case(lambda r, _: _detections_with_extra(r, "x: " + "[" * 50000 + "]" * 50000 + "\n"),
                                       "detections.yaml", "detect"),
    "calibration.json of 100 MB": Case(lambda r, _: (_write_calibration(r), open(r / "results" / "calibration.json",
                                                                                  "ab").truncate(100 * 10**6)),
                                       "calibration.json", "export --format json"),
    "calibration.json nested 100k deep": Case(lambda r, _: (_write_calibration(r), (r / "results" / "calibration.json")
                                                            .write_text("[" * 100000 + "]" * 100000)),
                                              "calibration.json", "export --format json"),
    "calibration.json with a 1e308 transform (report)": Case(lambda r, _: _write_calibration(r, [[1e308] * 4] * 4),
                                                            "calibration.json", "report", phrase="rigid"),
    "calibration.json with a 1e308 transform (plan)": Case(lambda r, _: _write_calibration(r, [[1e308] * 4] * 4),
                                                          "calibration.json", "plan", phrase="rigid"),
    "detections.yaml with a centre at 1e308 m (report)": Case(lambda r, _: (
        r / "detections.yaml").write_text("format: sonar-camera-detections/1\ncaptures:\n  p01:\n    sonar: "
                                          "{center: [1.0e+308, 0, 1.6], status: accepted}\n"), "detections.yaml", "report"),
    "session.yaml of 100 MB": Case(lambda r, _: open(r / "session.yaml", "ab").truncate(100 * 2**20), "session.yaml"),
    # image headers
    "JPEG claiming 30000 x 30000": Case(lambda r, _: _set_image(r, "big.jpg", _jpeg_claiming(30000, 30000)), "big.jpg"),
    "PNG claiming 30000 x 30000": Case(lambda r, _: _set_image(r, "big.png", _png_claiming(30000, 30000)), "big.png"),
    "BMP claiming 30000 x 30000": Case(lambda r, _: _set_image(r, "big.bmp", _bmp_claiming(30000, 30000)), "big.bmp"),
    "TIFF claiming 30000 x 30000": Case(lambda r, _: _set_image(r, "big.tiff", _tiff_claiming(30000, 30000)), "big.tiff"),
    "WebP claiming 16000 x 16000": Case(lambda r, _: _set_image(r, "big.webp", _webp_claiming(16000, 16000)), "big.webp"),
    "16-bit PNG of 36 MP (decodes to 288 MB)": Case(lambda r, _: _set_image(r, "deep.png", _png16_claiming(6000, 6000)),
                                                     "deep.png", phrase="decodes to"),
    "JPEG larger than its intrinsics": Case(lambda r, _: _set_image(r, "mid.jpg", _jpeg_claiming(4000, 3000)), "mid.jpg",
                                            phrase="intrinsics"),
    # clouds
    "LAS header with 768 M points and 2 G VLRs": Case(
        lambda r, _: _set_cloud(r, "bad.las", _las_header(768_000_000, n_vlr=2_000_000_000)), "bad.las"),
    "LAS header claiming a huge point count": Case(
        lambda r, _: _set_cloud(r, "huge.las", _las_header(4_000_000_000 - 1)), "huge.las"),
    "LAS header claiming more points than bytes": Case(
        lambda r, _: _set_cloud(r, "lying.las", _las_header(10_000)), "lying.las"),
    "LAZ header claiming 768 M points": Case(
        lambda r, _: _set_cloud(r, "bad.laz", _las_header(768_000_000, fmt=0x80)), "bad.laz"),
    "ASCII PLY with text in a number column": Case(_p01_ascii_ply_with_text, "p01.ply"),
    "ASCII PLY with a short row": Case(_p01_ascii_ply_short_row, "p01.ply"),
    "ASCII PLY with text (calibrate writes nothing)": Case(_p01_ascii_ply_with_text, "p01.ply", "calibrate"),
    "binary PCD with a lying count": Case(lambda r, _: _set_cloud(r, "lie.pcd", _pcd("binary", 10**9, bytes(1200))),
                                          "lie.pcd"),
    "ASCII PCD with a lying count": Case(lambda r, _: _set_cloud(r, "lie2.pcd", _pcd("ascii", 500, b"1 2 3\n" * 10)),
                                         "lie2.pcd"),
    "ASCII PCD with text": Case(lambda r, _: _set_cloud(r, "txt.pcd", _pcd("ascii", 3, b"1 2 3\n1 x 3\n1 2 3\n")),
                                "txt.pcd"),
    "compressed PCD with a lying size": Case(lambda r, _: _set_cloud(
        r, "lz.pcd", _pcd("binary_compressed", 100, struct.pack("<II", 16, 2**31) + bytes(16))), "lz.pcd"),
    "PCD whose WIDTH disagrees with POINTS": Case(lambda r, _: _set_cloud(r, "wh.pcd", _pcd("binary", 10, bytes(120))
                                                                           .replace(b"WIDTH 10", b"WIDTH 1000000000")),
                                                  "wh.pcd"),
    "binary PLY with a huge face element": Case(lambda r, _: _set_cloud(r, "faces.ply", (r / "clouds" / "p01.ply")
                                                                        .read_bytes().replace(
        b"end_header", b"element face 4000000000\nproperty list uchar int vertex_indices\nend_header", 1)), "faces.ply"),
    "binary PLY with a list property in the vertices, lying length": Case(lambda r, _: _set_cloud(
        r, "listy.ply", _ply_vertex_list(r)), "listy.ply", phrase="list property"),
    "binary PLY whose count lies low (10 of 300 rows)": Case(lambda r, _: _set_cloud(r, "low.ply", _ply_count_lying_low(r)),
                                                            "low.ply", phrase="point count"),
    "binary PCD whose count lies low (10 of 100 rows)": Case(lambda r, _: _set_cloud(
        r, "low.pcd", _pcd("binary", 10, np.ones((100, 3), "<f4").tobytes())), "low.pcd", phrase="point count"),
    "LAS whose count lies low (10 of 300 records)": Case(lambda r, _: _set_cloud(r, "low.las", _las_count_lying_low(r)),
                                                        "low.las", phrase="point count"),
    "LAS with scale factors of 1e308 (laspy's overflow warnings)": Case(
        lambda r, _: _set_cloud(r, "scale.las", _las_scaled(r, 1e308)), "scale.las", phrase="scale"),
    "LAS with scale factors of 0 (every point at the offset)": Case(
        lambda r, _: _set_cloud(r, "zero.las", _las_scaled(r, 0.0)), "zero.las", phrase="scale"),
    "PCD with SIZE 0 fields": Case(lambda r, _: _set_cloud(r, "z.pcd", _pcd("binary", 10**8, b"").replace(
        b"SIZE 4 4 4", b"SIZE 0 0 0")), "z.pcd"),
    "LAS 1.4 with an extended VLR claiming 2**62 bytes": Case(lambda r, _: _set_cloud(r, "evlr.las", _las14_evlr_bomb()),
                                                             "evlr.las"),
    ".npy with a huge shape": Case(lambda r, _: _set_cloud(r, "huge.npy", _npy_claiming((10**12, 3))), "huge.npy"),
    ".npy cloud of complex numbers": Case(lambda r, _: _set_cloud(r, "c.npy", _npy_bytes(np.ones((50, 3), complex))),
                                          "c.npy", phrase="complex128"),
    "text cloud that is one endless line": Case(lambda r, _: _set_cloud(r, "line.xyz", b"1 " * 400_000), "line.xyz"),
    # symlinks and writes outside the session
    "symlinked image outside": Case(lambda r, o: (
        (o / "img.png").write_bytes((r / "images" / "cam1" / "p01.png").read_bytes()),
        (r / "images" / "cam1" / "p01.png").unlink(), os.symlink(o / "img.png", r / "images" / "cam1" / "p01.png")),
        "session.yaml", phrase="leaves the session"),
    "symlinked cloud folder outside": Case(lambda r, o: (
        (o / "clouds").mkdir(), [os.replace(p, o / "clouds" / p.name) for p in (r / "clouds").iterdir()],
        (r / "clouds").rmdir(), os.symlink(o / "clouds", r / "clouds")), "session.yaml", phrase="leaves the session"),
    "session.yaml symlinked out of the session": Case(lambda r, o: (
        os.replace(r / "session.yaml", o / "session.yaml"), os.symlink(o / "session.yaml", r / "session.yaml")),
        "session.yaml", phrase="outside the session folder"),
    "results/ is a symlink out (calibrate)": Case(lambda r, o: _results_symlink(r, o / "res"), "calibration.json",
                                                  "calibrate --no-detect", phrase="outside the session folder"),
    "results/ is a symlink out (report)": Case(lambda r, o: _results_symlink(r, o / "res"), "results/", "report",
                                               phrase="outside the session folder"),
    "detections.yaml is a symlink out (detect)": Case(lambda r, o: (
        (o / "det.yaml").write_text("format: sonar-camera-detections/1\ncaptures: {}\n"),
        os.symlink(o / "det.yaml", r / "detections.yaml")), "detections.yaml", "detect"),
    "export into a symlinked results/": Case(lambda r, o: (_write_calibration(r), _relink_results(r, o / "res")),
                                             "calibration.json", "export --format tf2-yaml --out {root}/results/x.yaml",
                                             phrase="outside the session folder"),
    "export reading a calibration through results/ symlink": Case(
        lambda r, o: (_write_calibration(r), _relink_results(r, o / "res")), "calibration.json", "export --format json",
        phrase="outside the session folder"),
    # names that would forge lines or drive the terminal when a message shows them (session 25, sec)
    "image path with a newline and an escape": Case(lambda r, _: _edit_manifest(r, lambda d: d["captures"][0][
        "images"].update(cam1="images/cam1/a\x1b]0;owned\x07\nerror: forged.png")), "session.yaml",
        phrase="control characters"),
    "corrupt background frame named with a newline": Case(_corrupt_background_named_badly, "forged.png", "detect"),
    "background video that is not a video (FFmpeg's own log line)": Case(
        lambda r, _: _background_video(r, b"not a video\n" * 100), "bg.mp4", "detect"),
    "background video of 0 bytes": Case(lambda r, _: _background_video(r, b""), "bg.mp4", "detect", phrase="empty"),
    "info with detections.yaml symlinked out": Case(lambda r, o: (
        (o / "det.yaml").write_text("format: sonar-camera-detections/1\ncaptures: {}\n"),
        os.symlink(o / "det.yaml", r / "detections.yaml")), "detections.yaml", phrase="outside the session folder"),
}


def _write_calibration(root: Path, T=None) -> None:
    from calib_core.results import CALIBRATION_FORMAT, save_calibration

    T = np.eye(4).tolist() if T is None else T
    save_calibration(root / "results" / "calibration.json",
                     {"format": CALIBRATION_FORMAT, "cameras": {"cam1": {"T_cam_sonar": T}}})


def _relink_results(root: Path, outside: Path) -> None:
    """results/ becomes a symlink to a folder outside that holds the same calibration."""
    outside.mkdir()
    os.replace(root / "results" / "calibration.json", outside / "calibration.json")
    (root / "results").rmdir()
    os.symlink(outside, root / "results")


def _child_env() -> dict:
    """The child imports this checkout's code, whatever the caller's PYTHONPATH."""
    here = str(Path(__file__).resolve().parents[1])
    return dict(os.environ, COLUMNS="200", PYTHONPATH=os.pathsep.join([here, os.environ.get("PYTHONPATH", "")]))


def _prepare(name: str, case: Case, base: Path) -> dict:
    parent = base / name.replace(" ", "_").replace("/", "_")
    root = build_session(parent, n_captures=3, cameras=("cam1",), detections=False)
    outside = parent / "outside"
    outside.mkdir()
    case.corrupt(root, outside)
    cmd = case.command.replace("{root}", str(root)).split()
    return dict(name=name, argv=[cmd[0], str(root), *cmd[1:]], cwd=str(parent), root=root, parent=parent,
                before_root=tree_hash(root), before_parent=tree_hash(parent))


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """Every CLI case, run one after the other in one child process (see adversarial_launch.py)."""
    import json

    base = tmp_path_factory.mktemp("adv")
    prepared = [_prepare(name, case, base) for name, case in CASES.items()]
    (base / "cases.json").write_text(json.dumps([{k: p[k] for k in ("name", "argv", "cwd")} for p in prepared]))
    r = subprocess.run([sys.executable, str(LAUNCHER), str(base / "cases.json"), str(base / "results.json")],
                       capture_output=True, text=True, timeout=600, env=_child_env(), cwd=base)
    assert r.returncode == 0, r.stderr[-3000:]
    out = json.loads((base / "results.json").read_text())
    for p in prepared:
        out[p["name"]].update(root_same=tree_hash(p["root"]) == p["before_root"],
                              parent_same=tree_hash(p["parent"]) == p["before_parent"])
    return out


@pytest.mark.parametrize("name", list(CASES))
def test_cli_case_is_refused_in_one_line(results, name):
    case, r = CASES[name], results[name]
    detail = f"rc={r['rc']}\nstderr: {r['err'][-2000:]}\nstdout: {r['out'][-800:]}"
    assert r["rc"] == 2, detail
    lines = [ln for ln in r["err"].splitlines() if ln.strip() and not ln.endswith("problem(s):")]  # info's header
    assert len(lines) == 1, detail
    assert case.file in lines[0] and case.phrase.lower() in lines[0].lower(), detail
    assert "Traceback" not in r["err"] + r["out"] and "MemoryError" not in r["err"], detail
    assert "\x1b" not in r["err"] and "\u202e" not in r["err"], detail  # no terminal escape from a name
    assert 0 < r["peak_kb"] < PEAK_LIMIT_KB, f"peak memory {r['peak_kb'] / 1024:.0f} MB"
    assert 0 <= r["cpu"] < CPU_LIMIT_S, f"{r['cpu']:.1f} s of CPU"
    assert r["root_same"] and r["parent_same"], "a file changed or appeared in or beside the session"


# ---- the YAML reader itself -------------------------------------------------------------
@pytest.mark.parametrize("doc", [billion_laughs(), block_laughs(), merge_laughs(), "a: &x [*x]",
                                 "[" * 100 + "]" * 100, "- " * 200 + "x", "{a: " * 100 + "1" + "}" * 100])
def test_yaml_reader_refuses_bombs_and_depth(tmp_path, doc):
    from calib_core.errors import SessionError
    from calib_core.io.yaml_safe import read_yaml

    p = tmp_path / "f.yaml"
    p.write_text(doc)
    with pytest.raises(SessionError) as ei:
        read_yaml(p, "test file")
    assert ei.value.path == p and "\n" not in str(ei.value)


def test_yaml_reader_keeps_ordinary_aliases_and_unshares_them(tmp_path):
    from calib_core.io.yaml_safe import read_yaml

    p = tmp_path / "f.yaml"
    p.write_text("base: &b {fx: 1.5, list: [1, 2]}\ncopy: *b\nmerged: {<<: *b, fy: 2}\nname: Kamera ü 1\n")
    d = read_yaml(p)
    assert d["copy"] == d["base"] and d["copy"] is not d["base"] and d["copy"]["list"] is not d["base"]["list"]
    assert d["merged"] == {"fx": 1.5, "list": [1, 2], "fy": 2} and d["name"] == "Kamera ü 1"


def test_detections_save_writes_no_aliases(tmp_path):
    from calib_core.detections import load_detections, save_detections
    from calib_core.session import load_session

    root = build_session(tmp_path, n_captures=2, cameras=("cam1",))
    (root / "detections.yaml").write_text(
        "format: sonar-camera-detections/1\ncaptures:\n  p01:\n    sonar: &e {status: rejected, note: [a, b]}\n"
        "    cam1: *e\n")
    s = load_session(root)
    d = load_detections(s)
    save_detections(s, d)
    text = (root / "detections.yaml").read_text()
    assert "&" not in text and "*" not in text
    assert load_detections(s) == d


# ---- escaping ---------------------------------------------------------------------------
XSS = '<iframe srcdoc="<script>parent.x=1</script>"></iframe>'


def test_markup_helpers():
    from calib_core.markup import escape_html, escape_md, ros_frame_id

    assert escape_md("Kamera ü 1") == "Kamera ü 1" and escape_md("Sitzung über Wasser") == "Sitzung über Wasser"
    for text in (XSS, "<img src=x onerror=alert(1)>", "**bold** [x](javascript:alert(1)) `code` | a |\n# h"):
        md = escape_md(text)
        assert "<" not in md and ">" not in md and "\n" not in md
        assert "[x](" not in md and "**" not in md and "| a |" not in md
    assert escape_html(XSS).startswith("&lt;iframe srcdoc=&quot;") and "<" not in escape_html(XSS)
    for name, want in [("Kamera ü 1", "Kamera_u_1"), ("cam1", "cam1"), ("1st cam", "f_1st_cam"), ("", "frame"),
                       (XSS, None), ("robot/sonar", "robot/sonar"), ("a\nb", "a_b")]:
        got = ros_frame_id(name)
        assert all(seg and (seg[0].isalpha() or seg[0] == "_") and seg.replace("_", "").isalnum() or seg.replace("_", "") == ""
                   for seg in got.split("/")), got
        assert got.isascii() and (want is None or got == want)


def test_script_in_session_fields_stays_inert_in_workbench_and_report(tmp_path):
    from app.server import Workbench
    from calib_core.detections import load_detections
    from calib_core.report import build_report
    from calib_core.session import load_session

    root = build_session(tmp_path, n_captures=2, cameras=("cam1",))
    _edit_manifest(root, lambda d: (d.update(name=XSS), d["sonar"].update(model="<b>x</b>"),
                                    d["captures"][0].update(id="<img src=x onerror=alert(1)>")))
    (root / "detections.yaml").write_text(
        "format: sonar-camera-detections/1\ncaptures:\n  '<img src=x onerror=alert(1)>':\n"
        f"    sonar: {{status: rejected, reason: '{XSS}'}}\n")
    wb = Workbench(root, port=0, uploads_dir=tmp_path / "up")
    try:
        assert wb.wait_idle(60)
        wb.state.select("<img src=x onerror=alert(1)>")
        assert wb.wait_idle(60)
        wb.review.refresh()
        shown = [wb.title.content, wb.review.table.content, wb.review.details.content, wb.session_panel.info.content]
        for md in shown:
            assert "<iframe" not in md and "<img" not in md and "<b>" not in md, md
        assert "&lt;iframe" in wb.title.content and "&lt;img" in wb.review.details.content
    finally:
        wb.stop()
    s = load_session(root)
    html = build_report(s, None, load_detections(s))
    assert "<iframe" not in html and "<img src=x" not in html and "&lt;iframe" in html


def test_non_ascii_names_keep_working(tmp_path):
    from calib_core.export import FrameNames, to_tf_static
    from calib_core.session import load_session

    root = build_session(tmp_path, n_captures=2, cameras=("cam1",))
    _edit_manifest(root, lambda d: d.update(name="Sitzung über Wasser"))
    assert load_session(root).name == "Sitzung über Wasser"
    (root / "session.yaml").write_text((root / "session.yaml").read_text().replace(
        "name: Sitzung über Wasser", "name: 2026-05-01"))
    assert load_session(root).name == "2026-05-01"
    cal = {"format": "sonar-camera-calibration/1", "cameras": {"Kamera ü 1": {"T_cam_sonar": np.eye(4).tolist()}}}
    text = to_tf_static(cal, frames=FrameNames())
    assert "Kamera_u_1_optical_frame" in text and "# Kamera ü 1:" in text
    hostile = {"format": "sonar-camera-calibration/1", "cameras": {"x\nrm -rf ~": {"T_cam_sonar": np.eye(4).tolist()}}}
    assert "\nrm -rf" not in to_tf_static(hostile)


# ---- uploads ----------------------------------------------------------------------------
def _zip_bytes(entries: dict[str, bytes], symlink: str | None = None) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for n, data in entries.items():
            zf.writestr(n, data)
        if symlink:
            info = zipfile.ZipInfo("link")
            info.external_attr = (0o120777 << 16)
            zf.writestr(info, symlink)
    return buf.getvalue()


@pytest.mark.parametrize("kind", ["bomb", "symlink", "dotdot", "absolute", "not a zip", "duplicate", "file as folder",
                                  "long name", "deep path", "control characters"])
def test_hostile_zips_are_refused_and_leave_nothing(tmp_path, kind):
    from app.uploads import safe_unpack_zip
    from calib_core.errors import SessionError

    zpath = tmp_path / "up.zip"
    data = {"bomb": lambda: _zip_bytes({"session.yaml": b"a: 1", "big.bin": bytes(60 * 10**6)}),
            "symlink": lambda: _zip_bytes({"session.yaml": b"a: 1"}, symlink="/etc/passwd"),
            "dotdot": lambda: _zip_bytes({"../evil.txt": b"x"}),
            "absolute": lambda: _zip_bytes({"/tmp/evil.txt": b"x"}),
            "not a zip": lambda: b"PK\x03\x04" + os.urandom(2000),
            "duplicate": _dup_zip,
            "file as folder": lambda: _zip_bytes({"session.yaml": b"a: 1", "a": b"x", "a/b": b"y"}),
            # session 25 (sec): an OSError (name too long) escaped instead of a SessionError;
            # a name with a newline and an escape was unpacked as it was
            "long name": lambda: _zip_bytes({"session.yaml": b"a: 1", "x" * 300: b"1"}),
            "deep path": lambda: _zip_bytes({"session.yaml": b"a: 1", "a/" * 3000 + "f": b"1"}),
            "control characters": lambda: _zip_bytes({"session.yaml": b"a: 1", "bad\nname\x1b[31m.png": b"1"})}[kind]()
    zpath.write_bytes(data)
    dest = tmp_path / "uploads"
    with pytest.raises(SessionError) as ei:
        safe_unpack_zip(zpath, dest, label="up.zip", max_unpacked_bytes=50 * 10**6)
    assert "up.zip" in str(ei.value)
    assert not dest.exists() or not any(dest.iterdir())
    assert not (tmp_path / "evil.txt").exists()


def _dup_zip() -> bytes:
    import warnings

    buf = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with zipfile.ZipFile(buf, "w") as zf:
            zf.writestr("session.yaml", b"a: 1")
            zf.writestr("session.yaml", b"a: 2")
    return buf.getvalue()


class _FakeWs:
    def __init__(self):
        self.handlers, self.sent = {}, []

    def register_handler(self, cls, cb):
        self.handlers.setdefault(cls, []).append(cb)

    def unregister_handler(self, cls, cb):
        self.handlers[cls].remove(cb)

    def queue_message(self, m):
        self.sent.append(m)


def _fake_server():
    ws = _FakeWs()
    gui = SimpleNamespace(_handle_file_transfer_start=lambda c, m: ("viser", m),
                          _handle_file_transfer_part=lambda c, m: ("viser", m))
    from viser import _messages as vm

    ws.register_handler(vm.FileTransferStartUpload, gui._handle_file_transfer_start)
    ws.register_handler(vm.FileTransferPart, gui._handle_file_transfer_part)
    return SimpleNamespace(_websock_server=ws, gui=gui, on_client_disconnect=lambda cb: None)


def test_upload_is_refused_from_its_declared_size_and_streamed_to_disk(tmp_path):
    from viser import _messages as vm

    from app.upload_stream import UploadReceiver
    from app.uploads import MAX_UPLOAD_BYTES, UploadStore, upload_limit_text

    server, store = _fake_server(), UploadStore(tmp_path / "up")
    got, refused = [], []
    rx = UploadReceiver(server, SimpleNamespace(_impl=SimpleNamespace(uuid="btn")), store, MAX_UPLOAD_BYTES,
                        on_file=lambda c, n, p: got.append((n, p.read_bytes())), on_refuse=lambda c, n, why: refused.append(why))
    start = lambda tid, size, parts: rx._start(1, vm.FileTransferStartUpload(  # noqa: E731
        source_component_uuid="btn", transfer_uuid=tid, filename="s.zip", mime_type="application/zip",
        part_count=parts, size_bytes=size))
    part = lambda tid, i, data: rx._part(1, vm.FileTransferPart(  # noqa: E731
        source_component_uuid="btn", transfer_uuid=tid, part_index=i, content=data))
    start("big", MAX_UPLOAD_BYTES + 1, (MAX_UPLOAD_BYTES + 1) // 524288 + 1)
    part("big", 0, bytes(524288))
    assert refused and upload_limit_text().split()[-2] in refused[0] and "limit" in refused[0]
    assert "max 200 MB" == upload_limit_text() and "200 MB" in refused[0]
    assert not rx.transfers and not list(store.root.iterdir())  # nothing held, nothing on disk
    payload = os.urandom(3 * 524288 + 17)
    chunks = [payload[i:i + 524288] for i in range(0, len(payload), 524288)]
    start("ok", len(payload), len(chunks))
    for i, c in enumerate(chunks):
        assert len(rx.transfers) == 1 and not got
        part("ok", i, c)
    for _ in range(50):
        if got:
            break
        time.sleep(0.05)
    assert got == [("s.zip", payload)]
    start("liar", 10, 1)
    part("liar", 0, bytes(11))  # more bytes than declared: dropped, file deleted
    time.sleep(0.2)
    assert not rx.transfers and "do not match" in refused[-1]
    assert len([p for p in store.root.iterdir() if p.name.startswith("incoming-")]) == 1  # only the good one
    store.cleanup()
    assert not any(p.name.startswith("incoming-") for p in store.root.iterdir())


def test_replaced_upload_is_deleted_and_stop_cleans_up(tmp_path):
    from app.server import Workbench

    src = build_session(tmp_path / "src", n_captures=2, cameras=("cam1",))
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for p in src.rglob("*"):
            if p.is_file():
                zf.write(p, "s/" + str(p.relative_to(src)))
    wb = Workbench(build_session(tmp_path / "first", n_captures=2, cameras=("cam1",)), port=0)
    uploads = wb.uploads_dir
    try:
        assert wb.wait_idle(60)
        roots = []
        for _ in range(2):
            z = wb.uploads.incoming_file()
            z.write_bytes(buf.getvalue())
            wb.session_panel._on_upload(None, "s.zip", z)
            assert wb.wait_idle(60)
            roots.append(wb.state.session.root)
            assert not z.exists()
        assert roots[0] != roots[1] and not roots[0].exists() and roots[1].exists()
        assert len([p for p in uploads.iterdir()]) == 1
        wb.state.apply([("p01", "sonar", {"status": "rejected"})], client="test", action="reject")
        lock = wb.state.session.root / ".detections.yaml.lock"
        assert lock.exists()
    finally:
        wb.stop()
    assert not uploads.exists() and not lock.exists()


def test_serve_cleans_up_on_sigterm_and_warns_on_a_taken_port(tmp_path):
    import signal

    root = build_session(tmp_path, n_captures=2, cameras=("cam1",))
    blocker = socket.socket()
    blocker.bind(("127.0.0.1", 0))
    blocker.listen(1)
    port = blocker.getsockname()[1]
    env = dict(_child_env(), TMPDIR=str(tmp_path / "tmp"), COLUMNS="250")
    (tmp_path / "tmp").mkdir()
    proc = subprocess.Popen([sys.executable, "-m", "sonarcal_cli.main", "serve", str(root), "--port", str(port)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        out = ""
        deadline = time.monotonic() + 120
        while "press Ctrl+C" not in out and time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            out += line
        assert f"port {port} is taken" in out, out
        assert "?token=" in out
        bound = int(out.split("http://127.0.0.1:")[1].split("/")[0])
        for _ in range(3):  # bare TCP connects and garbage: no traceback in the log
            with socket.create_connection(("127.0.0.1", bound)) as s:
                s.sendall(b"\x16\x03\x01garbage\r\n\r\n")
        time.sleep(0.5)
        assert any(p.name.startswith("sonarcal-uploads-") for p in (tmp_path / "tmp").iterdir())
        proc.send_signal(signal.SIGTERM)
        rest_out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
        blocker.close()
    assert proc.returncode == 0, err
    assert "Traceback" not in err + rest_out and "handshake" not in err, err
    assert not any((tmp_path / "tmp").iterdir()), "uploads folder left behind"
    assert not (root / ".detections.yaml.lock").exists()


# ---- network clients ------------------------------------------------------------------------
def test_tokenless_or_cross_origin_clients_read_and_change_nothing(tmp_path):
    import msgspec
    import viser
    from websockets.sync.client import connect

    from app.server import Workbench

    root = build_session(tmp_path, n_captures=2, cameras=("cam1",))
    wb = Workbench(root, port=0, uploads_dir=tmp_path / "up")
    try:
        assert wb.wait_idle(60)
        before = tree_hash(root)
        base = f"ws://127.0.0.1:{wb.port}/"
        proto = [f"viser-v{viser.__version__}"]
        click = msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": "any", "updates": {"value": True}})
        attempts = [dict(url=base), dict(url=base + "?token=wrong"),
                    dict(url=base + f"?token={wb.token}", origin="http://evil.example"),
                    dict(url=base, origin=f"http://127.0.0.1:{wb.port}"),
                    dict(url=base, additional_headers={"Cookie": f"sonarcal_token_{wb.port}=wrong"}),
                    dict(url=base + f"?token={wb.token}", origin="null")]
        for kw in attempts:
            url = kw.pop("url")
            with pytest.raises(Exception) as ei:
                ws = connect(url, subprotocols=proto, open_timeout=10, **kw)
                ws.send(click)
                ws.recv(timeout=2)
            assert "403" in str(ei.value), str(ei.value)
        assert wb.server.get_clients() == {} and tree_hash(root) == before
        import urllib.error
        import urllib.request

        with pytest.raises(urllib.error.HTTPError) as he:
            urllib.request.urlopen(f"http://127.0.0.1:{wb.port}/", timeout=10)
        assert he.value.code == 403
        ws = connect(base + f"?token={wb.token}", subprotocols=proto, open_timeout=10,
                     origin=f"http://127.0.0.1:{wb.port}")  # the owner, for contrast
        assert len(ws.recv(timeout=10)) > 0
        ws.close()
    finally:
        wb.stop()


def test_background_symlink_out_and_opencv_cap(tmp_path):
    from calib_core.errors import SessionError
    from calib_core.io.images import load_background_frames
    from calib_core.session import validate_session

    root = build_session(tmp_path, n_captures=2, cameras=("cam1",), background=True)
    outside = tmp_path / "secret.png"
    outside.write_bytes((root / "backgrounds" / "cam1" / "bg0.png").read_bytes())
    os.symlink(outside, root / "backgrounds" / "cam1" / "bg2.png")
    with pytest.raises(SessionError, match="leaves the session"):
        load_background_frames(root / "backgrounds" / "cam1", root=root)
    assert any("bg2.png" in str(p) for p in validate_session(root).problems)
    assert os.environ.get("OPENCV_IO_MAX_IMAGE_PIXELS") == "40000000"  # set when calib_core is imported


def test_no_token_mode_keeps_the_origin_and_host_checks(tmp_path):
    import urllib.request

    import viser
    from websockets.sync.client import connect

    from app.server import Workbench

    wb = Workbench(build_session(tmp_path, n_captures=2, cameras=("cam1",)), port=0, uploads_dir=tmp_path / "up",
                   token=None)
    try:
        assert wb.url == f"http://127.0.0.1:{wb.port}/" and wb.token is None
        base, proto = f"ws://127.0.0.1:{wb.port}/", [f"viser-v{viser.__version__}"]
        ws = connect(base, subprotocols=proto, open_timeout=10, origin=f"http://127.0.0.1:{wb.port}")
        assert len(ws.recv(timeout=10)) > 0
        ws.close()
        for kw in (dict(origin="http://evil.example"), dict(additional_headers={"Host": f"evil.example:{wb.port}"})):
            with pytest.raises(Exception, match="403"):
                connect(base, subprotocols=proto, open_timeout=10, **kw)
        assert urllib.request.urlopen(wb.url, timeout=10).status == 200
    finally:
        wb.stop()


def test_cli_tables_print_names_as_plain_text():
    from rich.console import Console

    from sonarcal_cli.ui import table

    con = Console(record=True, width=200)
    con.print(table("Captures of [/bold]x", ["capture", "[red]"], [["[/bold]p01[link=file:///etc]", "[/]"]]))
    text = con.export_text()
    assert "[/bold]p01[link=file:///etc]" in text and "Captures of [/bold]x" in text


def test_uploads_through_a_real_websocket(tmp_path):
    """The receiver really replaces viser's handlers: an over-size upload is refused from its first
    message and never stored; a good one is streamed to disk and opened."""
    import msgspec
    import viser
    from websockets.sync.client import connect

    from app.server import Workbench
    from app.uploads import MAX_UPLOAD_BYTES

    src = build_session(tmp_path / "src", n_captures=2, cameras=("cam1",))
    _edit_manifest(src, lambda d: d.update(name="uploaded over the wire"))
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for p in src.rglob("*"):
            if p.is_file():
                zf.write(p, "s/" + str(p.relative_to(src)))
    payload = buf.getvalue()
    wb = Workbench(build_session(tmp_path / "first", n_captures=2, cameras=("cam1",)), port=0,
                   uploads_dir=tmp_path / "up")
    try:
        assert wb.wait_idle(60)
        ws = connect(f"ws://127.0.0.1:{wb.port}/?token={wb.token}", subprotocols=[f"viser-v{viser.__version__}"],
                     open_timeout=10, max_size=None)
        uuid = wb.session_panel.upload._impl.uuid
        send = lambda **m: ws.send(msgspec.msgpack.encode(m))  # noqa: E731
        send(type="FileTransferStartUpload", source_component_uuid=uuid, transfer_uuid="big", filename="big.zip",
             mime_type="application/zip", part_count=500, size_bytes=MAX_UPLOAD_BYTES + 1)
        send(type="FileTransferPart", source_component_uuid=uuid, transfer_uuid="big", part_index=0,
             content=bytes(524288))
        half = (len(payload) + 1) // 2
        send(type="FileTransferStartUpload", source_component_uuid=uuid, transfer_uuid="ok", filename="s.zip",
             mime_type="application/zip", part_count=2, size_bytes=len(payload))
        for i in range(2):
            send(type="FileTransferPart", source_component_uuid=uuid, transfer_uuid="ok", part_index=i,
                 content=payload[i * half:(i + 1) * half])
        deadline = time.monotonic() + 60
        while wb.state.session.name != "uploaded over the wire" and time.monotonic() < deadline:
            try:
                ws.recv(timeout=0.2)
            except TimeoutError:
                pass
        assert wb.state.session.name == "uploaded over the wire"
        assert "big" in wb.session_panel.receiver.refused and "big" not in wb.session_panel.receiver.transfers
        assert not [p for p in (tmp_path / "up").iterdir() if p.name.startswith("incoming-")]
        ws.close()
    finally:
        wb.stop()
