"""BlueView BV5000 ProScan ``.off`` point clouds (Geomview colour OFF layout, points only).

Layout: line 1 ``OFF`` or ``COFF``; line 2 ``N_POINTS N_FACES N_EDGES``; then ``N_POINTS`` rows
``X Y Z R G B A`` (metres, colour 0-255 or 0-1); a points-only file has no face rows. The
parse is strict (every row has the same 7 numbers, the count matches the header) and reads
in chunks into arrays sized from the header, which is first checked against the file size.
The point's intensity is the mean of R, G and B (ProScan colours points by echo strength).
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np

from calib_core.errors import SessionError
from calib_core.io.las_header import MAX_CLOUD_POINTS

MIN_ROW_BYTES = 14  # "0 0 0 0 0 0 0\n"
CHUNK_ROWS = 200_000


def read_off(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(N,3) points in metres and (N,) intensity from a ProScan ``.off`` file."""
    path = Path(path)
    with open(path, "rb") as f:
        n, n_faces = _header(path, f)
        if n > MAX_CLOUD_POINTS:
            raise SessionError(path, f"header claims {n} points: more than the {MAX_CLOUD_POINTS} this tool loads")
        if n * MIN_ROW_BYTES > path.stat().st_size:
            raise SessionError(path, f"header declares {n} points but the file is too small to hold them (truncated?)")
        pts, inten = np.empty((n, 3)), np.empty(n)
        with io.TextIOWrapper(f, encoding="ascii", errors="strict") as tf:
            done = 0
            while done < n:
                chunk = _chunk(path, tf, min(CHUNK_ROWS, n - done), done)
                k = len(chunk)
                if k == 0:
                    raise SessionError(path, f"file is truncated: header declares {n} points, found {done}")
                pts[done:done + k], inten[done:done + k] = chunk[:, :3], chunk[:, 3:6].mean(axis=1)
                done += k
            rest = tf.read(4096).strip()
            if rest and (n_faces == 0 or not re.match(r"^\d+\s+\d", rest)):  # only declared face rows may follow
                raise SessionError(path, f"more rows than the {n} points the header declares")
    return pts, inten


def _header(path: Path, f) -> tuple[int, int]:
    first = f.readline(64).strip()
    if first not in (b"OFF", b"COFF"):
        raise SessionError(path, "not a ProScan .off file (first line must be OFF or COFF)")
    second = f.readline(256).split()
    try:
        counts = [int(v) for v in second]
    except ValueError:
        counts = []
    if len(counts) != 3 or min(counts) < 0:
        raise SessionError(path, "line 2 must be three counts: points faces edges")
    if counts[0] == 0:
        raise SessionError(path, "point cloud holds no points (its header declares 0)")
    return counts[0], counts[1]


def _chunk(path: Path, tf, rows: int, done: int) -> np.ndarray:
    try:
        arr = np.loadtxt(tf, max_rows=rows, ndmin=2, dtype=np.float64, comments=None)
    except (ValueError, UnicodeDecodeError) as e:
        why = str(e).splitlines()[0][:80] if str(e) else type(e).__name__
        raise SessionError(path, f"bad point row after point {done} (expected X Y Z R G B A): {why}") from None
    if arr.size and arr.shape[1] != 7:
        raise SessionError(path, f"point rows must have 7 numbers (X Y Z R G B A), found {arr.shape[1]}")
    return arr
