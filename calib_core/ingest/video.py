"""``import_video``: one camera's video plus a CSV of scan times and the sonar's cloud files.

The CSV has a header row ``id,start_s,end_s,cloud``: one row per scan, times in seconds into
the video, ``cloud`` a point cloud file (any format :func:`calib_core.io.clouds.load_cloud`
reads, .off included) relative to the CSV. The video is read once, frame by frame.
"""

from __future__ import annotations

import csv
import re
from pathlib import Path

import cv2

from calib_core.errors import SessionError
from calib_core.ingest.assemble import MAX_BACKGROUND_FRAMES, Assembler, ImportOptions, ImportResult
from calib_core.ingest.frames import FrameKeeper
from calib_core.ingest.motion import NS
from calib_core.ingest.scans import ScanWindow, scan_index
from calib_core.ingest.staging import StagedSession
from calib_core.io.clouds import load_cloud
from calib_core.io.intrinsics import load_intrinsics

MAX_CSV_ROWS = 10_000
MAX_CSV_BYTES = 16 * 2**20  # 10 000 rows of id, two times and a cloud path are well under 2 MB


def read_scan_csv(path: Path) -> list[tuple[str, float, float, Path]]:
    """Rows (id, start_s, end_s, cloud path) of a scan-times CSV, checked."""
    if not path.is_file():
        raise SessionError(path, "scan-times CSV not found")
    if path.stat().st_size > MAX_CSV_BYTES:
        raise SessionError(path, f"scan-times CSV is {path.stat().st_size / 2**20:.0f} MiB: far more than "
                                 f"{MAX_CSV_ROWS} rows of scan times")
    try:
        rows = _csv_rows(path)
    except csv.Error as e:  # a field over csv's 128 kB limit, a NUL byte: was an internal error
        raise SessionError(path, f"not a scan-times CSV ({e})") from None
    except UnicodeDecodeError:
        raise SessionError(path, "not a text file (invalid UTF-8)") from None
    if not rows:
        raise SessionError(path, "no scan rows")
    ids = [r[0] for r in rows]
    if len(set(ids)) != len(ids):
        raise SessionError(path, "capture ids are not unique")
    return rows


def _csv_rows(path: Path) -> list[tuple[str, float, float, Path]]:
    rows = []
    with open(path, newline="", encoding="utf-8-sig") as f:
        reader = csv.DictReader(f)
        need = {"id", "start_s", "end_s", "cloud"}
        if reader.fieldnames is None or not need <= {h.strip() for h in reader.fieldnames}:
            raise SessionError(path, "expected a header row with columns id,start_s,end_s,cloud")
        for n, row in enumerate(reader, 2):
            if n > MAX_CSV_ROWS:
                raise SessionError(path, f"more than {MAX_CSV_ROWS} rows")
            row = {k.strip(): (v or "").strip() for k, v in row.items() if k}
            rows.append(_row(path, n, row))
    return rows


def _row(path: Path, n: int, row: dict):
    cid = row["id"]
    if not re.fullmatch(r"[A-Za-z0-9_.-]{1,64}", cid):
        raise SessionError(path, f"line {n}: id {cid!r} must be letters, digits, '_', '-' or '.'")
    try:
        a, b = float(row["start_s"]), float(row["end_s"])
    except ValueError:
        raise SessionError(path, f"line {n}: start_s and end_s must be numbers") from None
    if not (0 <= a < b < 1e7):
        raise SessionError(path, f"line {n}: need 0 <= start_s < end_s")
    return cid, a, b, (path.parent / row["cloud"]).resolve()


def import_video(video: Path, scans_csv: Path, camera: str, out, opts: ImportOptions, progress=None) -> ImportResult:
    rows = read_scan_csv(scans_csv)
    if camera not in opts.intrinsics:
        raise SessionError(video, f"a video needs the camera's intrinsics: --intrinsics {camera}=FILE")
    model = load_intrinsics(opts.intrinsics[camera], camera, opts.intrinsics_entry.get(camera))
    windows = [ScanWindow(int(a * NS), int(b * NS), 1) for _, a, b, _ in rows]
    keeper = FrameKeeper({camera: model}, opts.diameter_m / 2, windows, 0, opts.tolerance_px, opts.tolerance_m,
                         opts.median)
    cap = cv2.VideoCapture(str(video))
    if not video.is_file() or not cap.isOpened():
        raise SessionError(video, "cannot open video (missing, corrupt or unsupported codec)")
    try:
        fps = cap.get(cv2.CAP_PROP_FPS)
        if not (0 < fps < 10_000):
            raise SessionError(video, "video reports no frame rate")
        with StagedSession(out) as st:
            asm = Assembler(st, opts, windows, 0, ids=[r[0] for r in rows])
            bg = _read_frames(cap, fps, video, windows, keeper, opts, rows, asm, progress)
            cam_entry = {"intrinsics": st.intrinsics(camera, model)}
            if bg:
                for j, f in enumerate(bg):
                    cam_entry["background"] = st.image("backgrounds", camera, f"bg{j:02d}", f).rsplit("/", 1)[0] + "/"
            src = {"kind": "video", "path": str(video.absolute()), "scans_csv": str(scans_csv.absolute()),
                   "fps": float(fps), "cameras": {camera: {"video": str(video.absolute())}}}
            return asm.manifest({camera: cam_entry}, src, video.stem)
    finally:
        cap.release()


def _read_frames(cap, fps, video, windows, keeper: FrameKeeper, opts, rows, asm: Assembler, progress) -> list:
    from calib_core.detect.image.detect import background_model

    camera = next(iter(keeper.cams))
    bgw = opts.background_window_s
    bg, done, k = [], 0, 0
    while done < len(windows):
        if not cap.grab():
            break
        t_ns = int(k / fps * NS)
        i = scan_index(windows, t_ns)
        in_bg = bgw is not None and bgw[0] <= k / fps <= bgw[1] and len(bg) < MAX_BACKGROUND_FRAMES
        if i >= 0 or in_bg:
            ok, bgr = cap.retrieve()
            if not ok:
                raise SessionError(video, f"frame {k} cannot be decoded (truncated video?)")
            rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
            if i < 0:
                bg.append(rgb)
            else:
                if bg and camera not in keeper.backgrounds:
                    keeper.set_background(camera, background_model(bg))
                try:
                    keeper.add(camera, i, t_ns, rgb)
                except ValueError as e:
                    raise SessionError(video, f"frame {k}: {e}") from None
        while done < len(windows) and windows[done].end_ns < t_ns:
            _finish(asm, keeper, rows, done)
            done += 1
            if progress:
                progress(done, len(windows), rows[done - 1][0])
        k += 1
    for j in range(done, len(windows)):
        _finish(asm, keeper, rows, j)
    return bg


def _finish(asm: Assembler, keeper: FrameKeeper, rows, i: int) -> None:
    frames, motion = keeper.take(i)
    cloud = load_cloud(rows[i][3])
    inten = None if cloud.intensity is None else [cloud.intensity]
    asm.finish_scan(i, [cloud.points_m], inten, frames, motion, 1)
