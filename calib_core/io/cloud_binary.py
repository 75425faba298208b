"""Binary PLY and binary PCD point clouds read with numpy (no open3d).

Importing open3d takes about a second; every detection worker used to pay it for a few
thousand points. Headers were already checked against the file size
(:mod:`calib_core.io.cloud_headers`), so exactly the declared rows are there. Files this
reader does not cover (a variable-length element before the vertices of a PLY, a
``binary_compressed`` PCD) return None and are left to open3d; a list property inside the vertex
element is refused (open3d reads a lying list length on into garbage rows and exits 0).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calib_core.errors import SessionError
from calib_core.io.cloud_ascii import INTENSITY_NAMES, header_lines, pcd_header

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
_PCD_KINDS = {"F": "f", "I": "i", "U": "u"}


def read_binary_ply(path: Path):
    """(points, intensity or None) of a binary PLY's vertices, or None for open3d to read."""
    lines, offset = header_lines(path, "end_header")
    order = ">" if any(ln.split()[:2] == ["format", "binary_big_endian"] for ln in lines) else "<"
    elements = _ply_layout(lines)
    skip = 0
    for name, count, props in elements:
        if props is None and name == "vertex":  # open3d reads a lying list length on: garbage points, exit 0
            raise SessionError(path, "PLY 'vertex' element holds a list property: rows of varying length are not "
                                     "supported (write x, y, z and intensity as plain properties)")
        if props is None:
            return None  # a list property before the vertices (faces first): rows of varying size
        if name == "vertex":
            return _ply_vertices(path, offset + skip, count, props, order)
        skip += count * sum(np.dtype(t).itemsize for _, t in props)
    return None


def _ply_layout(lines: list[str]) -> list[list]:
    """[name, count, [(property, numpy type)] or None when a list property makes rows vary]."""
    elements: list[list] = []
    for line in lines:
        parts = line.split()
        if parts[:1] == ["element"] and len(parts) == 3:
            elements.append([parts[1], int(parts[2]), []])
        elif parts[:1] == ["property"] and elements and elements[-1][2] is not None:
            elements[-1][2] = None if parts[1] == "list" else elements[-1][2] + [(parts[2], _PLY_TYPES[parts[1]])]
    return elements


def _ply_vertices(path: Path, offset: int, n: int, props: list, order: str):
    names = [p for p, _ in props]
    if not {"x", "y", "z"} <= set(names) or len(set(names)) != len(names):
        raise SessionError(path, "cannot read the points (corrupt file, or not a point cloud)")
    dtype = np.dtype([(p, order + t) for p, t in props])
    rows = _rows(path, offset, n, dtype)
    return _fields(rows, names)


def read_binary_pcd(path: Path):
    """(points, intensity or None) of a PCD with ``DATA binary``, or None for open3d to read."""
    fields, offset = pcd_header(path)
    if [v.lower() for v in fields.get("DATA", [])[:1]] != ["binary"]:
        return None
    names = fields["FIELDS"]
    sizes = [int(v) for v in fields.get("SIZE", ["4"] * len(names))]
    types = fields.get("TYPE", ["F"] * len(names))
    counts = [int(v) for v in fields.get("COUNT", ["1"] * len(names))]
    if len(types) != len(names) or any(t.upper() not in _PCD_KINDS for t in types):
        raise SessionError(path, "PCD header is malformed (FIELDS and TYPE disagree)")
    n = int(fields["POINTS"][0]) if "POINTS" in fields else \
        int(fields["WIDTH"][0]) * int(fields.get("HEIGHT", ["1"])[0])
    unique = [nm if nm not in names[:k] else f"_{k}" for k, nm in enumerate(names)]  # "_" padding fields repeat
    dtype = np.dtype([(nm, "<" + _PCD_KINDS[t.upper()] + str(s), (c,) if c > 1 else ())
                      for nm, t, s, c in zip(unique, types, sizes, counts)])
    return _fields(_rows(path, offset, n, dtype), unique)


def _rows(path: Path, offset: int, n: int, dtype: np.dtype) -> np.ndarray:
    with open(path, "rb") as f:
        f.seek(offset)
        buf = f.read(n * dtype.itemsize)
    if len(buf) < n * dtype.itemsize:  # the header check makes this unreachable; kept as a guard
        raise SessionError(path, f"file is truncated: header says {n} points")
    return np.frombuffer(buf, dtype=dtype, count=n)


def _fields(rows: np.ndarray, names: list[str]):
    pts = np.column_stack([rows[a].astype(np.float64).reshape(len(rows)) for a in ("x", "y", "z")])
    keys = {k.lower(): k for k in names}
    inten = next((rows[keys[k]].astype(np.float64).reshape(-1) for k in INTENSITY_NAMES if k in keys), None)
    return pts, inten


def needs_open3d(path: Path) -> bool:
    """True when ``path`` is a PLY / PCD these readers leave to open3d (unreadable files: False,
    their loader names the problem)."""
    suffix = path.suffix.lower()
    if suffix not in (".ply", ".pcd"):
        return False
    try:
        with open(path, "rb") as f:
            head = f.read(65536)
    except OSError:
        return False
    if suffix == ".pcd":
        return b"binary_compressed" in head
    end = head.find(b"end_header")
    return b"property list" in head[: end if end >= 0 else len(head)] and b"binary" in head[:end]
