"""Strict readers for ASCII PLY and ASCII PCD (numpy, no open3d).

open3d's ASCII readers stop at a row with text in it and still return the declared number
of points, the rest uninitialised memory (1e19, 1e-44 ...). Here every one of the
declared rows must hold the declared number of numbers, or the file is refused with the
line that is wrong. Headers were already checked against the file size
(:mod:`calib_core.io.cloud_headers`).
"""

from __future__ import annotations

import io
import itertools
from pathlib import Path

import numpy as np

from calib_core.errors import SessionError

INTENSITY_NAMES = ("intensity", "intensities", "scalar_intensity", "reflectance")
_HEAD_BYTES = 65536


def header_lines(path: Path, end_token: str) -> tuple[list[str], int]:
    """Header lines up to and including ``end_token``'s line, and the byte offset after it."""
    with open(path, "rb") as f:
        head = f.read(_HEAD_BYTES)
    lines, offset = [], 0
    for raw in head.splitlines(keepends=True):
        offset += len(raw)
        line = raw.decode("latin-1").strip()
        lines.append(line)
        if line.split()[:1] == [end_token]:
            return lines, offset
    raise SessionError(path, f"header is incomplete (no '{end_token}' line)")


def _rows(path: Path, offset: int, skip: int, n: int, ncols: int) -> np.ndarray:
    """Exactly ``n`` rows of ``ncols`` numbers after ``skip`` rows, from byte ``offset``."""
    with open(path, "rb") as f:
        f.seek(offset)
        text = io.TextIOWrapper(f, encoding="latin-1", newline=None)
        lines = (ln for ln in text if ln.strip())
        for _ in itertools.islice(lines, skip):
            pass
        rows = itertools.islice(lines, n)
        try:
            arr = np.loadtxt(rows, dtype=np.float64, ndmin=2, comments=None)
        except ValueError as e:
            raise SessionError(path, f"a point row is not {ncols} numbers ({_short(e)})") from None
    if arr.shape != (n, ncols):
        got = arr.shape[0] if arr.shape[1:] == (ncols,) else "rows of the wrong length"
        raise SessionError(path, f"header declares {n} points of {ncols} values, the file holds {got}")
    return arr  # NaN/inf rows are the caller's policy (load_cloud refuses or drops them)


def _short(e: Exception) -> str:
    text = str(e).splitlines()[0] if str(e) else type(e).__name__
    return text.split(";")[0].rstrip(". ")[:100]


def read_ascii_ply(path: Path):
    """(points (N,3), intensity or None) from an ASCII PLY's vertex element."""
    lines, offset = header_lines(path, "end_header")
    skip, vertex, props = 0, None, None
    elements: list[tuple[str, int, list]] = []
    for line in lines:
        parts = line.split()
        if parts[:1] == ["element"] and len(parts) == 3:
            elements.append((parts[1], int(parts[2]), []))
        elif parts[:1] == ["property"] and elements:
            elements[-1][2].append(parts[1:])
    for name, count, plist in elements:
        if name == "vertex":
            vertex, props = count, plist
            break
        if any(p[:1] == ["list"] for p in plist):
            raise SessionError(path, "ASCII PLY with list elements before the vertices is not supported")
        skip += count
    if vertex is None or props is None:
        raise SessionError(path, "PLY file has no 'element vertex' (not a point cloud)")
    if any(p[:1] == ["list"] for p in props):
        raise SessionError(path, "ASCII PLY vertices with list properties are not supported")
    names = [p[-1].lower() for p in props]
    if not {"x", "y", "z"} <= set(names):
        raise SessionError(path, f"PLY vertices have no x y z properties ({' '.join(names)})")
    arr = _rows(path, offset, skip, vertex, len(names))
    cols = [names.index(c) for c in "xyz"]
    inten = next((arr[:, names.index(k)] for k in INTENSITY_NAMES if k in names), None)
    return arr[:, cols], inten


def pcd_header(path: Path) -> tuple[dict[str, list[str]], int]:
    """A PCD header as {KEYWORD: [values]} (FIELDS, SIZE, TYPE, COUNT, POINTS, DATA, ...) and the
    byte offset of the data after it."""
    lines, offset = header_lines(path, "DATA")
    fields: dict[str, list[str]] = {}
    for line in lines:
        parts = line.split()
        if parts and parts[0].isupper():
            fields[parts[0]] = parts[1:]
    return fields, offset


def read_ascii_pcd(path: Path):
    """(points (N,3), intensity or None) from an ASCII PCD."""
    fields, offset = pcd_header(path)
    names = [n.lower() for n in fields["FIELDS"]]
    counts = [int(v) for v in fields.get("COUNT", ["1"] * len(names))]
    n = int(fields["POINTS"][0]) if "POINTS" in fields else int(fields["WIDTH"][0]) * int(fields.get("HEIGHT", ["1"])[0])
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int)
    arr = _rows(path, offset, 0, n, int(sum(counts)))
    col = {name: int(s) for name, s in zip(names, starts)}
    inten = next((arr[:, col[k]] for k in INTENSITY_NAMES if k in col), None)
    return arr[:, [col["x"], col["y"], col["z"]]], inten
