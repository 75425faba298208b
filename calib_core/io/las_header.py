"""LAS/LAZ and .npy headers checked against the file before any reader allocates.

``laspy.read`` trusts the header: a 4 kB corrupt file claimed 768 M points and 2 G VLRs
and took 6 GB. ``np.load`` trusts the shape in a .npy header. Here the counts are read
from the fixed-layout headers and compared with the file's size and a point cap.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from calib_core.errors import SessionError

MAX_CLOUD_POINTS = 20_000_000  # a sonar scan holds well under a million points
MAX_LAZ_RATIO = 60  # LAZ compresses points 5-15x; a header claiming much more lies
_MIN_RECORD = {0: 20, 1: 28, 2: 26, 3: 34, 4: 57, 5: 63, 6: 30, 7: 36, 8: 38, 9: 59, 10: 67}


def check_las_header(path: Path) -> int:
    """Validate a LAS/LAZ public header block against the file size; return the point count."""
    size = path.stat().st_size
    with open(path, "rb") as f:
        head = f.read(375)
    if len(head) < 227 or head[:4] != b"LASF":
        raise SessionError(path, "not a LAS/LAZ file (no 'LASF' signature or header too short)")
    major, minor = head[24], head[25]
    header_size, offset, n_vlr = struct.unpack_from("<HII", head, 94)
    fmt_raw, rec_len, legacy_n = struct.unpack_from("<BHI", head, 104)
    if major != 1 or minor > 4 or header_size < 227 or header_size > len(head) + 10_000:
        raise SessionError(path, f"LAS header is corrupt (version {major}.{minor}, header size {header_size})")
    n = legacy_n
    if minor >= 4 and len(head) >= 255:
        n = struct.unpack_from("<Q", head, 247)[0] or legacy_n
    compressed = bool(fmt_raw & 0xC0) or path.suffix.lower() == ".laz"
    fmt = fmt_raw & 0x3F
    if fmt not in _MIN_RECORD or rec_len < _MIN_RECORD[fmt]:
        raise SessionError(path, f"LAS header is corrupt (point format {fmt}, record length {rec_len})")
    if not header_size <= offset <= size or n_vlr * 54 > offset - header_size:
        raise SessionError(path, f"LAS header is corrupt: {n_vlr} VLRs and point data at byte {offset} "
                                 f"do not fit a {size}-byte file")
    if n > MAX_CLOUD_POINTS:
        raise SessionError(path, f"LAS header claims {n} points: more than the {MAX_CLOUD_POINTS} this tool loads")
    _check_scale_offset(path, head)
    data_bytes = size - offset
    if not compressed and n * rec_len > data_bytes:
        raise SessionError(path, f"file is truncated or its header is corrupt: {n} points of {rec_len} bytes "
                                 f"need {n * rec_len} bytes, the file holds {data_bytes}")
    if compressed and n * rec_len > data_bytes * MAX_LAZ_RATIO:
        raise SessionError(path, f"LAZ header claims {n} points, far more than {data_bytes} compressed bytes can hold")
    evlr_start = n_evlr = 0
    if minor >= 4 and len(head) >= 247:
        evlr_start, n_evlr = struct.unpack_from("<QI", head, 235)
        if n_evlr and (evlr_start > size or n_evlr * 60 > size - evlr_start):
            raise SessionError(path, f"LAS header is corrupt: {n_evlr} extended VLRs do not fit the file")
        _check_evlrs(path, evlr_start, n_evlr, size)
    if not compressed:
        _check_no_extra_records(path, head, minor, offset, n, rec_len, evlr_start if n_evlr else size, size)
    return int(n)


def _check_no_extra_records(path: Path, head: bytes, minor: int, offset: int, n: int, rec_len: int,
                            evlr_start: int, size: int) -> None:
    """A whole point record more than the header declares, before whatever follows the points
    (LAS 1.3 waveform data, LAS 1.4 extended VLRs): a count lying low silently dropped the rest."""
    end = min(size, evlr_start)
    if minor >= 3 and len(head) >= 235:
        waveform_start = struct.unpack_from("<Q", head, 227)[0]
        if offset < waveform_start < end:
            end = waveform_start
    extra = end - offset - n * rec_len
    if extra >= rec_len:
        raise SessionError(path, f"file holds {extra // rec_len} more point records than its header's point count "
                                 f"({n}): the count is wrong (or the file was appended to)")


MAX_LAS_SCALE = 1e3  # metres per integer step; real files use 1e-4 to 1
MAX_LAS_OFFSET = 1e9  # metres; UTM or ECEF offsets are below 1e7


def _check_scale_offset(path: Path, head: bytes) -> None:
    """Scale factors and offsets that make coordinates at all (scale 0: every point at the offset;
    1e308: overflow warnings from laspy on stderr and infinite points)."""
    scale, offset = np.array(struct.unpack_from("<3d", head, 131)), np.array(struct.unpack_from("<3d", head, 155))
    with np.errstate(invalid="ignore"):
        ok = (np.abs(scale) > 0).all() and (np.abs(scale) <= MAX_LAS_SCALE).all() \
            and (np.abs(offset) <= MAX_LAS_OFFSET).all()
    if not ok:
        raise SessionError(path, f"LAS header is corrupt: scale factors {scale.tolist()} and offsets {offset.tolist()} "
                                 f"(scale 0 < |s| <= {MAX_LAS_SCALE:g}, offsets at most {MAX_LAS_OFFSET:.0e} m)")


def _check_evlrs(path: Path, start: int, count: int, size: int) -> None:
    """Each extended VLR declares a 64-bit length: they must all fit in the file."""
    pos = start
    with open(path, "rb") as f:
        for _ in range(count):
            f.seek(pos + 20)
            raw = f.read(8)
            if len(raw) < 8:
                raise SessionError(path, "LAS file is truncated inside its extended VLRs")
            pos += 60 + struct.unpack("<Q", raw)[0]
            if pos > size:
                raise SessionError(path, "LAS header is corrupt: an extended VLR claims more bytes than the file holds")


def check_npy_header(path: Path) -> None:
    """Refuse a .npy whose header's shape and dtype do not match the file size (or exceed the cap)."""
    from numpy.lib import format as npformat

    size = path.stat().st_size
    try:
        with open(path, "rb") as f:
            version = npformat.read_magic(f)
            reader = npformat.read_array_header_1_0 if version == (1, 0) else npformat.read_array_header_2_0
            shape, _fortran, dtype = reader(f, max_header_size=10_000)
            offset = f.tell()
    except (ValueError, OSError, SyntaxError, TypeError, struct.error, EOFError):
        raise SessionError(path, "not a valid .npy file (bad magic or header)") from None
    if dtype.hasobject:
        raise SessionError(path, "the .npy file holds Python objects, not numbers")
    count = int(np.prod(shape, dtype=object)) if shape else 1
    if count > MAX_CLOUD_POINTS * 4:
        raise SessionError(path, f"the .npy header claims shape {shape}: more than {MAX_CLOUD_POINTS} points")
    if count * dtype.itemsize != size - offset:
        raise SessionError(path, f"the .npy header claims shape {shape} of {dtype}, "
                                 f"{count * dtype.itemsize} bytes; the file holds {size - offset}")
