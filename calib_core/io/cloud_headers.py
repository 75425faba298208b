"""Header checks for PLY and PCD files, run *before* open3d reads them.

open3d zero-fills or silently shortens truncated files and prints warnings on stderr
instead of raising, so a half-copied file must be caught here: the header says how many
points (and bytes or lines) follow; the file must hold at least that much.
"""

from __future__ import annotations

import re
from pathlib import Path

from calib_core.errors import SessionError

_PLY_SIZES = {"char": 1, "int8": 1, "uchar": 1, "uint8": 1, "short": 2, "int16": 2, "ushort": 2, "uint16": 2,
              "int": 4, "int32": 4, "uint": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}
_HEAD_BYTES = 65536


def check_cloud_header(path: Path) -> int:
    """Validate a .ply/.pcd header against the file's size; return the declared point count."""
    with open(path, "rb") as f:
        head = f.read(_HEAD_BYTES)
    if path.suffix.lower() == ".ply":
        return _check_ply(path, head)
    return _check_pcd(path, head)


def _split_header(path: Path, head: bytes, end_token: bytes, what: str) -> tuple[str, int]:
    i = head.find(end_token)
    if i < 0:
        raise SessionError(path, f"{what} header is incomplete (no '{end_token.decode().strip()}' line)")
    j = head.find(b"\n", i)
    if j < 0:
        j = len(head) - 1
    return head[: j + 1].decode("latin-1"), j + 1


def _count_rows(path: Path, offset: int) -> tuple[int, bytes]:
    """Non-blank lines after ``offset`` and the last of them, reading in chunks (bounded memory)."""
    rows, last, carry = 0, b"", b""
    with open(path, "rb") as f:
        f.seek(offset)
        while True:
            chunk = f.read(1 << 22)
            if not chunk:
                break
            lines = (carry + chunk).split(b"\n")
            carry = lines.pop()
            full = [ln for ln in lines if ln.strip()]
            rows += len(full)
            if full:
                last = full[-1]
    if carry.strip():
        rows, last = rows + 1, carry
    return rows, last


def _check_ply(path: Path, head: bytes) -> int:
    if not head.startswith(b"ply"):
        raise SessionError(path, "not a PLY file (it does not start with 'ply')")
    text, header_len = _split_header(path, head, b"end_header", "PLY")
    m = re.search(r"^format\s+(\w+)", text, re.M)
    if not m or m.group(1) not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise SessionError(path, "PLY header has no valid 'format' line")
    elements = _ply_elements(path, text)
    vertex = next((e for e in elements if e[0] == "vertex"), None)
    if vertex is None:
        raise SessionError(path, "PLY file has no 'element vertex' (not a point cloud)")
    n = vertex[1]
    if n < 0:
        raise SessionError(path, f"PLY header: negative vertex count {n}")
    size = path.stat().st_size
    for name, count, _ in elements:  # every row of every element takes at least one byte
        if count < 0 or count > size:
            raise SessionError(path, f"PLY header claims {count} '{name}' rows, more than the file's {size} bytes")
    if m.group(1) != "ascii":
        _check_ply_binary(path, elements, header_len, size)
    else:
        _check_ply_ascii(path, elements, vertex, header_len)
    return n


def _ply_elements(path: Path, text: str) -> list[list]:
    """[name, count, [property types] or None when a list property makes rows variable] per element."""
    elements: list[list] = []
    for line in text.splitlines():
        parts = line.split()
        if parts[:1] == ["element"] and len(parts) == 3:
            try:
                elements.append([parts[1], int(parts[2]), []])
            except ValueError:
                raise SessionError(path, f"PLY header: bad element line {line!r}") from None
        elif parts[:1] == ["property"] and elements:
            if len(parts) >= 2 and parts[1] == "list":
                elements[-1][2] = None
            elif elements[-1][2] is not None:
                if len(parts) != 3 or parts[1] not in _PLY_SIZES:
                    raise SessionError(path, f"PLY header: bad property line {line!r}")
                elements[-1][2].append(parts[1])
    return elements


def _check_ply_binary(path: Path, elements: list, header_len: int, size: int) -> None:
    need = header_len
    for name, count, props in elements:  # fixed-size elements up to (and including) the vertices
        if props is None:
            break
        need += count * sum(_PLY_SIZES[p] for p in props)
        if name == "vertex":
            break
    if size < need:
        raise SessionError(path, f"file is truncated: {size} bytes, its header needs at least {need}")
    if all(props is not None for _, _, props in elements):  # every row of a fixed size: the total is known
        rows = [(name, count * sum(_PLY_SIZES[p] for p in props), sum(_PLY_SIZES[p] for p in props))
                for name, count, props in elements]
        total = header_len + sum(nbytes for _, nbytes, _ in rows)
        vertex_row = next(row for name, _, row in rows if name == "vertex")
        _check_no_extra_rows(path, size - total, vertex_row)


def _check_no_extra_rows(path: Path, extra: int, row_bytes: int) -> None:
    """A whole point row more than the header declares (padding shorter than a row is left
    alone): a count that lies low would silently drop the points after it."""
    if row_bytes and extra >= row_bytes:
        raise SessionError(path, f"file holds {extra // row_bytes} more point rows than its header's point count: "
                                 "the count is wrong (or the file was appended to)")


def _check_ply_ascii(path: Path, elements: list, vertex: list, header_len: int) -> None:
    n = vertex[1]
    before = 0
    for name, count, _ in elements:
        if name == "vertex":
            break
        before += count
    rows, last = _count_rows(path, header_len)
    if rows < before + n:
        raise SessionError(path, f"file is truncated: header says {n} points, the file holds {max(rows - before, 0)} rows")
    nprops = len(vertex[2]) if vertex[2] is not None else None
    if n and nprops is not None and len(elements) == 1 and rows == n and len(last.split()) != nprops:
        raise SessionError(path, f"file is truncated or corrupt: the last point row does not hold {nprops} values")


def _check_pcd(path: Path, head: bytes) -> int:
    if b"FIELDS" not in head or b"DATA" not in head:
        raise SessionError(path, "not a PCD file (no FIELDS/DATA header)")
    m = re.search(rb"^DATA[ \t]+(\w+)[^\n]*\n", head, re.M)
    if not m:
        raise SessionError(path, "PCD header is incomplete (no 'DATA' line)")
    header_len = m.end()
    names, sizes, counts, n = _pcd_fields(path, head[:header_len].decode("latin-1"))
    kind = m.group(1).decode("latin-1").lower()
    size = path.stat().st_size
    row_bytes = sum(s * c for s, c in zip(sizes, counts))
    if kind == "binary":
        need = header_len + n * row_bytes
        if size < need:
            raise SessionError(path, f"file is truncated: {size} bytes, its header needs at least {need}")
        _check_no_extra_rows(path, size - need, row_bytes)
    elif kind == "binary_compressed":
        _check_pcd_compressed(path, header_len, n, row_bytes, size)
    elif kind == "ascii":
        rows, last = _count_rows(path, header_len)
        if rows < n:
            raise SessionError(path, f"file is truncated: header says {n} points, the file holds {rows} rows")
        if n and rows == n and len(last.split()) != sum(counts):
            raise SessionError(path, f"file is truncated or corrupt: the last point row does not hold {sum(counts)} values")
    else:
        raise SessionError(path, f"PCD data kind '{kind}' is not supported (ascii, binary, binary_compressed)")
    return n


def _pcd_fields(path: Path, text: str) -> tuple[list[str], list[int], list[int], int]:
    """(field names, sizes, counts, point count) of a PCD header, checked for consistency."""
    fields: dict[str, list[str]] = {}
    for line in text.splitlines():
        parts = line.split()
        if parts and parts[0].isupper():
            fields[parts[0]] = parts[1:]
    try:
        names = fields["FIELDS"]
        sizes = [int(v) for v in fields.get("SIZE", ["4"] * len(names))]
        counts = [int(v) for v in fields.get("COUNT", ["1"] * len(names))]
        wh = int(fields["WIDTH"][0]) * int(fields.get("HEIGHT", ["1"])[0]) if "WIDTH" in fields else None
        n = int(fields["POINTS"][0]) if "POINTS" in fields else wh
        if n is None or (wh is not None and wh != n):
            raise ValueError("WIDTH x HEIGHT and POINTS disagree")
    except (KeyError, ValueError, IndexError):
        raise SessionError(path, "PCD header is malformed (FIELDS/SIZE/COUNT/POINTS)") from None
    if len(sizes) != len(names) or len(counts) != len(names) or n < 0 or \
            any(s not in (1, 2, 4, 8) for s in sizes) or any(c < 1 or c > 4096 for c in counts):
        raise SessionError(path, "PCD header is malformed (FIELDS, SIZE and COUNT disagree)")
    if not {"x", "y", "z"} <= set(names):
        raise SessionError(path, f"PCD file has no x y z fields (fields: {' '.join(names)})")
    return names, sizes, counts, n


def _check_pcd_compressed(path: Path, header_len: int, n: int, row_bytes: int, size: int) -> None:
    with open(path, "rb") as f:
        f.seek(header_len)
        sizes_raw = f.read(8)
    if len(sizes_raw) < 8:
        raise SessionError(path, "file is truncated: compressed PCD data is missing")
    compressed = int.from_bytes(sizes_raw[:4], "little")
    uncompressed = int.from_bytes(sizes_raw[4:], "little")
    if uncompressed != n * row_bytes:
        raise SessionError(path, f"PCD header is corrupt: {n} points need {n * row_bytes} "
                                 f"bytes unpacked, the data block says {uncompressed}")
    if size < header_len + 8 + compressed:
        raise SessionError(path, f"file is truncated: {size} bytes, its header needs at least {header_len + 8 + compressed}")
