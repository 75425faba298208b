"""Point cloud files: .ply .pcd (numpy; open3d for compressed PCD), .xyz .csv .txt, .npy, .las .laz (laspy).

Every loader returns a :class:`Cloud` with finite float64 points in metres, or
raises :class:`SessionError` naming the file and the problem.
"""

from __future__ import annotations

import io
import itertools
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib_core.errors import SessionError
from calib_core.io.las_header import MAX_CLOUD_POINTS, check_las_header, check_npy_header
from calib_core.io.off import read_off

MAX_CLOUD_BYTES = 2 * 2**30  # a sonar scan is tens of MB; anything this big is a wrong file
# farther than any sensor measures, in metres or millimetres: a coordinate beyond this is a driver's
# "no return" marker (FLT_MAX) or a corrupt value, and would overflow the detectors' voxel grids
MAX_COORD = 1e7
CLOUD_SUFFIXES = (".ply", ".pcd", ".xyz", ".csv", ".txt", ".npy", ".las", ".laz", ".off")


@dataclass(frozen=True)
class Cloud:
    """A sonar point cloud in the sonar frame.

    Attributes:
        points_m: (N,3) float64, metres, all finite.
        intensity: (N,) float64 or None.
        n_without_return: rows of the file that held NaN or infinite coordinates or exactly
            (0, 0, 0) (the ways PCL's organised clouds, depth cameras and many LiDAR drivers mark
            "no return"); dropped.
    """

    points_m: np.ndarray
    intensity: np.ndarray | None = None
    n_without_return: int = 0

    def __len__(self) -> int:
        return len(self.points_m)


def _checked_file(path: Path) -> str:
    """The cloud file's suffix (lower case), after checking it exists, has a known format and a
    size this tool loads."""
    if not path.is_file():
        raise SessionError(path, "point cloud file not found")
    suffix = path.suffix.lower()
    if suffix not in CLOUD_SUFFIXES:
        raise SessionError(path, f"unknown point cloud format '{suffix}' (use one of {', '.join(CLOUD_SUFFIXES)})")
    size = path.stat().st_size
    if size == 0:
        raise SessionError(path, "point cloud file is empty (0 bytes)")
    if size > MAX_CLOUD_BYTES:
        raise SessionError(path, f"point cloud file is {size / 2**30:.1f} GiB, more than the {MAX_CLOUD_BYTES / 2**30:.0f} GiB "
                                 "this tool loads (thin the cloud or crop it to the work area)")
    return suffix


def load_cloud(path: str | Path, allow_nonfinite: bool = True) -> Cloud:
    """Load a point cloud; reject empty clouds. Points with NaN or infinite coordinates mean
    "no return" in organised clouds (PCL, depth cameras, LiDAR drivers): they are dropped and
    counted (``Cloud.n_without_return``), as are points at exactly (0, 0, 0), the sensor's own
    origin; a cloud with nothing else is refused.
    ``allow_nonfinite=False`` refuses NaN or infinite points instead (points at exactly
    (0, 0, 0) are dropped and counted either way)."""
    path = Path(path)
    suffix = _checked_file(path)
    try:
        pts, inten = _READERS[suffix](path)
    except SessionError:
        raise
    except MemoryError:
        raise SessionError(path, "cannot read point cloud: it needs more memory than this machine has "
                                 "(corrupt header, or a far too large cloud)") from None
    except Exception as e:  # corrupt or truncated file: name it, no traceback
        detail = str(e).strip().splitlines()[0][:120] if str(e).strip() else "no detail"
        raise SessionError(path, f"cannot read point cloud ({type(e).__name__}: {detail})") from None
    pts = np.asarray(pts, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise SessionError(path, f"expected N x 3 points, got shape {pts.shape}")
    if len(pts) == 0:
        raise SessionError(path, "point cloud holds no points")
    with np.errstate(invalid="ignore"):
        finite = (np.abs(pts) <= MAX_COORD).all(axis=1)  # False for NaN, infinite and absurdly far points
    if not allow_nonfinite and not finite.all():
        raise SessionError(path, f"{int((~finite).sum())} of {len(pts)} points are NaN or infinite (or farther "
                                 f"than {MAX_COORD:.0e} from the origin)")
    keep = finite & pts.any(axis=1)  # exactly (0, 0, 0), the sensor's own origin, is how many drivers write "no return"
    if inten is not None:
        inten = np.asarray(inten, dtype=np.float64).reshape(-1)
        if len(inten) != len(pts):
            inten = None
    if not keep.all():
        if not keep.any():
            raise SessionError(path, f"point cloud holds no return: all {len(pts)} points are NaN, infinite, "
                                     f"farther than {MAX_COORD:.0e} or (0, 0, 0)")
        pts = pts[keep]
        inten = None if inten is None else inten[keep]
    return Cloud(pts, inten, int(len(keep) - len(pts)))


def save_cloud(path: str | Path, cloud: Cloud) -> None:
    """Write a cloud; the format follows the suffix (.ply binary, .pcd binary, .npy, .xyz, .las)."""
    from calib_core.io.atomic import atomic_write_bytes

    path = Path(path)
    suffix = path.suffix.lower()
    pts = np.asarray(cloud.points_m, dtype=np.float64)
    inten = cloud.intensity
    if suffix == ".npy":
        arr = pts if inten is None else np.column_stack([pts, inten])
        buf = io.BytesIO()
        np.save(buf, arr)
        atomic_write_bytes(path, buf.getvalue())
    elif suffix in (".xyz", ".txt", ".csv"):
        arr = pts if inten is None else np.column_stack([pts, inten])
        sep = "," if suffix == ".csv" else " "
        buf = io.StringIO()
        np.savetxt(buf, arr, fmt="%.6f", delimiter=sep)
        atomic_write_bytes(path, buf.getvalue().encode())
    elif suffix == ".ply":
        atomic_write_bytes(path, _ply_bytes(pts, inten))
    elif suffix == ".pcd":
        atomic_write_bytes(path, _pcd_bytes(pts, inten))
    elif suffix in (".las", ".laz"):
        import laspy

        header = laspy.LasHeader(point_format=0, version="1.2")
        header.scales = np.array([1e-4, 1e-4, 1e-4])
        header.offsets = np.floor(pts.min(axis=0)) if len(pts) else np.zeros(3)
        las = laspy.LasData(header)
        las.x, las.y, las.z = pts[:, 0], pts[:, 1], pts[:, 2]
        if inten is not None:
            las.intensity = np.clip(inten, 0, 65535).astype(np.uint16)
        buf = io.BytesIO()
        las.write(buf, do_compress=suffix == ".laz")
        atomic_write_bytes(path, buf.getvalue())
    else:
        raise SessionError(path, f"cannot write point cloud format '{suffix}'")


# ---- writers (binary little-endian, float32 xyz like the sonar software writes) ----
def _ply_bytes(pts: np.ndarray, inten: np.ndarray | None) -> bytes:
    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")] + ([("intensity", "<f4")] if inten is not None else [])
    rec = np.empty(len(pts), dtype=fields)
    rec["x"], rec["y"], rec["z"] = pts[:, 0], pts[:, 1], pts[:, 2]
    if inten is not None:
        rec["intensity"] = inten
    head = "ply\nformat binary_little_endian 1.0\n" f"element vertex {len(pts)}\n"
    head += "".join(f"property float {n}\n" for n, _ in fields) + "end_header\n"
    return head.encode() + rec.tobytes()


def _pcd_bytes(pts: np.ndarray, inten: np.ndarray | None) -> bytes:
    names = ["x", "y", "z"] + (["intensity"] if inten is not None else [])
    arr = pts if inten is None else np.column_stack([pts, inten])
    head = (
        "# .PCD v0.7\nVERSION 0.7\n"
        f"FIELDS {' '.join(names)}\nSIZE {' '.join('4' * len(names))}\n"
        f"TYPE {' '.join('F' * len(names))}\nCOUNT {' '.join('1' * len(names))}\n"
        f"WIDTH {len(arr)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(arr)}\nDATA binary\n"
    )
    return head.encode() + arr.astype("<f4").tobytes()


# ---- readers -------------------------------------------------------------
def _read_ply_pcd(path: Path):
    """PLY/PCD: ASCII and plain binary files with numpy, the rest through open3d.

    The header is checked first (open3d zero-fills truncated files and only warns).
    """
    from calib_core.io.cloud_headers import check_cloud_header

    n_declared = check_cloud_header(path)
    if n_declared == 0:
        raise SessionError(path, "point cloud holds no points (its header declares 0)")
    if n_declared > MAX_CLOUD_POINTS:
        raise SessionError(path, f"header claims {n_declared} points: more than the {MAX_CLOUD_POINTS} this tool loads")
    if _is_ascii(path):  # open3d fills the rows after a bad one with uninitialised memory
        from calib_core.io.cloud_ascii import read_ascii_pcd, read_ascii_ply

        return (read_ascii_ply if path.suffix.lower() == ".ply" else read_ascii_pcd)(path)
    from calib_core.io.cloud_binary import read_binary_pcd, read_binary_ply

    out = (read_binary_ply if path.suffix.lower() == ".ply" else read_binary_pcd)(path)
    return out if out is not None else _read_open3d(path, n_declared)


def _read_open3d(path: Path, n_declared: int):
    """PLY/PCD through open3d's tensor API (keeps an intensity field); open3d's own warnings
    are silenced, our SessionError says what is wrong."""
    import open3d as o3d

    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        pcd = o3d.t.io.read_point_cloud(str(path))
    if "positions" not in pcd.point or len(pcd.point.positions) == 0:
        raise SessionError(path, "cannot read the points (corrupt file, or not a point cloud)")
    pts = pcd.point.positions.numpy()
    inten = None
    keys = {k.lower(): k for k in pcd.point}
    for key in ("intensity", "intensities", "scalar_intensity", "reflectance"):
        if key in keys:
            inten = pcd.point[keys[key]].numpy().reshape(-1)
            break
    if len(pts) != n_declared:
        raise SessionError(path, f"file is truncated or corrupt: header says {n_declared} points, read {len(pts)}")
    return pts, inten


def _is_ascii(path: Path) -> bool:
    """True for an ASCII PLY or ASCII PCD (headers already checked)."""
    with open(path, "rb") as f:
        head = f.read(65536)
    if path.suffix.lower() == ".ply":
        return re.search(rb"^format\s+ascii\b", head, re.M) is not None
    return re.search(rb"^DATA[ \t]+ascii\b", head, re.M | re.I) is not None


def _read_text(path: Path):
    fast = _read_text_fast(path)
    if fast is not None:
        return fast
    return _read_text_rows(path)


def _read_text_fast(path: Path):
    """numpy's C parser, streaming from the file, for the common regular file (bounded memory).

    Returns None when the file is irregular (odd header, ragged rows, bad bytes); then the
    row-by-row reader below parses it or says which line is wrong.
    """
    with open(path, "rb") as f:
        offset, first = 0, None
        for i in range(1000):  # blank, comment and non-numeric header rows before the data
            line = f.readline(4096)
            if not line or (len(line) == 4096 and not line.endswith(b"\n")):
                return None
            try:
                s = line.decode("utf-8-sig" if i == 0 else "utf-8").strip()
            except UnicodeDecodeError:
                return None
            if s and not s.startswith("#"):
                try:
                    [float(p) for p in re.split(r"[,\s;]+", s) if p]
                    first = s
                    break
                except ValueError:
                    pass
            offset += len(line)
        if first is None:
            return None
        delim = "," if "," in first else ";" if ";" in first else None
        f.seek(offset)
        with io.TextIOWrapper(f, encoding="utf-8", errors="strict", newline=None) as tf:
            try:
                with warnings.catch_warnings():  # numpy notes that blank lines do not count as rows
                    warnings.simplefilter("ignore", UserWarning)
                    arr = np.loadtxt(tf, delimiter=delim, comments="#", ndmin=2, dtype=np.float64,
                                     max_rows=MAX_CLOUD_POINTS + 1)
            except (ValueError, UnicodeDecodeError):
                return None
    if arr.ndim != 2 or arr.shape[1] < 3 or len(arr) == 0:
        return None
    if len(arr) > MAX_CLOUD_POINTS:
        raise SessionError(path, f"more than {MAX_CLOUD_POINTS} points: more than this tool loads")
    return arr[:, :3], (arr[:, 3] if arr.shape[1] >= 4 else None)


_MAX_TEXT_LINE = 65536


def _text_lines(path: Path):
    """(line number, text) of a text cloud, streamed; refuses binary data and endless lines."""
    with open(path, "rb") as f:
        for lineno in itertools.count(1):
            raw = f.readline(_MAX_TEXT_LINE)
            if not raw:
                return
            if len(raw) == _MAX_TEXT_LINE and not raw.endswith(b"\n"):
                raise SessionError(path, f"line {lineno} is longer than {_MAX_TEXT_LINE} bytes (not a text point cloud)")
            try:
                yield lineno, raw.decode("utf-8-sig" if lineno == 1 else "utf-8")
            except UnicodeDecodeError:
                raise SessionError(path, "not a text point cloud (invalid UTF-8: binary data?)") from None


def _read_text_rows(path: Path):
    rows = []
    for lineno, line in _text_lines(path):
        if len(rows) > MAX_CLOUD_POINTS:
            raise SessionError(path, f"more than {MAX_CLOUD_POINTS} points: more than this tool loads")
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        parts = [p for p in re.split(r"[,\s;]+", s) if p]
        try:
            vals = [float(p) for p in parts]
        except ValueError:
            if not rows:  # a header row
                continue
            raise SessionError(path, f"line {lineno}: not a number row: {s[:60]!r}") from None
        if len(vals) < 3:
            raise SessionError(path, f"line {lineno}: expected x y z [intensity], got {len(vals)} values")
        rows.append(vals[:4] if len(vals) >= 4 else vals[:3] + [np.nan])
    if not rows:
        raise SessionError(path, "point cloud holds no points")
    arr = np.array(rows, dtype=np.float64)
    inten = arr[:, 3] if np.isfinite(arr[:, 3]).all() else None
    return arr[:, :3], inten


def _read_npy(path: Path):
    check_npy_header(path)
    arr = np.load(path, allow_pickle=False)
    real = np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)  # not complex, not text
    if arr.ndim != 2 or arr.shape[1] not in (3, 4) or not real:
        raise SessionError(path, f"expected an (N,3) or (N,4) number array, got {arr.dtype} {arr.shape}")
    return arr[:, :3], (arr[:, 3] if arr.shape[1] == 4 else None)


def _read_las(path: Path):
    import laspy

    n_declared = check_las_header(path)
    las = laspy.read(str(path))
    pts = np.column_stack([np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)])
    if len(pts) != n_declared:
        raise SessionError(path, f"file is truncated or corrupt: header says {n_declared} points, read {len(pts)}")
    inten = np.asarray(las.intensity, dtype=np.float64) if "intensity" in las.point_format.dimension_names else None
    return pts, inten


_READERS = {
    ".ply": _read_ply_pcd,
    ".pcd": _read_ply_pcd,
    ".xyz": _read_text,
    ".csv": _read_text,
    ".txt": _read_text,
    ".npy": _read_npy,
    ".las": _read_las,
    ".laz": _read_las,
    ".off": read_off,
}
