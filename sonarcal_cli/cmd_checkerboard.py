"""``sonarcal intrinsics FOLDER`` and ``sonarcal stereo FOLDER1 FOLDER2``: checkerboard calibration.

Registers two subcommands (this module is the "checkerboard" entry of main.COMMANDS).
"""

from __future__ import annotations

from rich.markup import escape

import math
from pathlib import Path

import numpy as np

from calib_core.errors import SessionError
from sonarcal_cli.ui import console, progress_bar, table


def add_parser(sub) -> None:
    p = sub.add_parser("intrinsics", help="camera intrinsics from a folder of checkerboard images (ROS camera_info YAML)")
    p.add_argument("folder", help="folder of checkerboard images from one camera")
    p.add_argument("--pattern", default="9x6", help="inner corners COLSxROWS (default 9x6)")
    p.add_argument("--square", type=float, required=True, help="square size in metres, e.g. 0.025")
    p.add_argument("--name", default=None, help="camera name written into the file (default: the output file's stem)")
    p.add_argument("--k3", action="store_true", help="also estimate k3 (default: held at 0, as ROS does)")
    p.add_argument("--out", required=True, help="output ROS camera_info YAML, e.g. intrinsics/cam1.yaml")
    p.set_defaults(run=run_intrinsics)

    s = sub.add_parser("stereo", help="stereo transform T_cam2_cam1 from simultaneous checkerboard images of two cameras")
    s.add_argument("folder1", help="checkerboard images of camera 1")
    s.add_argument("folder2", help="checkerboard images of camera 2 (paired with folder1 by file name, else by order)")
    s.add_argument("--pattern", default="9x6", help="inner corners COLSxROWS (default 9x6)")
    s.add_argument("--square", type=float, required=True, help="square size in metres")
    s.add_argument("--intrinsics1", default=None, help="camera 1 intrinsics (default: calibrated from folder1)")
    s.add_argument("--intrinsics2", default=None, help="camera 2 intrinsics (default: calibrated from folder2)")
    s.add_argument("--names", nargs=2, default=["cam1", "cam2"], metavar=("CAM1", "CAM2"),
                   help="camera names for the key T_<CAM2>_<CAM1> (default cam1 cam2)")
    s.add_argument("--out", required=True, help="output YAML with the stereo transform")
    s.set_defaults(run=run_stereo)


def _load(paths):
    from calib_core.io.images import load_image

    return [(n, load_image(p)) for n, p in paths]


def _check_square(v: float) -> None:
    if not (math.isfinite(v) and 0 < v < 1.0):
        raise SessionError(None, f"--square {v} must be the square size in metres (e.g. 0.025)")


def run_intrinsics(args) -> int:
    from calib_core.io.intrinsics import save_intrinsics_ros
    from calib_core.solve.checkerboard import calibrate_intrinsics, folder_images, parse_pattern

    pattern = parse_pattern(args.pattern)
    _check_square(args.square)
    out = Path(args.out)
    name = args.name or out.stem
    images = _load(folder_images(args.folder))
    with progress_bar("checkerboard") as cb:
        try:
            res = calibrate_intrinsics(images, pattern, args.square, name=name, fix_k3=not args.k3, progress=cb)
        except SessionError as e:
            raise SessionError(e.path or Path(args.folder), e.problem) from None
    save_intrinsics_ros(out, res.cam, name)
    c = res.cam
    console.print(f"[bold]{escape(name)}[/bold]: {c.width_px} x {c.height_px}, fx {c.fx:.2f} fy {c.fy:.2f} "
                  f"cx {c.cx:.2f} cy {c.cy:.2f} (1-sigma {res.sigma.get('fx', float('nan')):.2f} / "
                  f"{res.sigma.get('fy', float('nan')):.2f} / {res.sigma.get('cx', float('nan')):.2f} / "
                  f"{res.sigma.get('cy', float('nan')):.2f} px)")
    console.print("distortion k1 k2 p1 p2 k3: " + " ".join(f"{v:.5f}" for v in c.dist))
    rows = [[n, f"{e:.3f}"] for n, e in res.per_image_rms_px.items()]
    rows += [[n, f"skipped: {r}"] for n, r in res.skipped.items()]
    console.print(table(f"Per-image reprojection RMS (px), {len(res.per_image_rms_px)} used", ["image", "RMS px"], rows))
    console.print(f"reprojection RMS {res.rms_px:.3f} px; wrote {out}")
    return 0


def run_stereo(args) -> int:
    from calib_core.io.atomic import atomic_write_yaml
    from calib_core.io.intrinsics import load_intrinsics
    from calib_core.solve.checkerboard import calibrate_intrinsics, calibrate_stereo, pair_folders, parse_pattern
    from calib_core.solve.model import log_so3

    pattern = parse_pattern(args.pattern)
    _check_square(args.square)
    n1, n2 = args.names
    pairs = pair_folders(args.folder1, args.folder2)
    loaded = [(n, a, b) for (n, a), (_, b) in zip(_load([(n, p) for n, p, _ in pairs]), _load([(n, p) for n, _, p in pairs]))]
    cams = []
    for which, path, folder, idx in ((n1, args.intrinsics1, args.folder1, 1), (n2, args.intrinsics2, args.folder2, 2)):
        if path:
            cams.append(load_intrinsics(path))
        else:
            imgs = [(t[0], t[idx]) for t in loaded]
            with progress_bar(f"{which} intrinsics") as cb:
                try:
                    r = calibrate_intrinsics(imgs, pattern, args.square, name=which, progress=cb)
                except SessionError as e:
                    raise SessionError(e.path or Path(folder), e.problem) from None
            console.print(f"{which}: intrinsics from {folder} (RMS {r.rms_px:.3f} px; give --intrinsics{idx} to use a file)")
            cams.append(r.cam)
    with progress_bar("stereo") as cb:
        try:
            res = calibrate_stereo(loaded, cams[0], cams[1], pattern, args.square, progress=cb)
        except SessionError as e:
            raise SessionError(e.path or Path(args.folder1), e.problem) from None
    key = f"T_{n2}_{n1}"
    T = res.T_cam2_cam1
    doc = {"format": "sonar-camera-stereo/1", key: [[float(v) for v in row] for row in T],
           f"cov_{key}": [[float(v) for v in row] for row in res.cov], "rms_reprojection_px": res.rms_px,
           "per_pair_rms_px": res.per_pair_rms_px, "skipped": res.skipped,
           "note": f"copy '{key}' into session.yaml under 'stereo:' (and the covariance under 'stereo_covariance:')"}
    atomic_write_yaml(args.out, doc)
    sig = np.sqrt(np.diag(res.cov))
    console.print(f"[bold]{key}[/bold]: baseline {1000 * np.linalg.norm(T[:3, 3]):.1f} mm, rotation "
                  f"{math.degrees(np.linalg.norm(log_so3(T[:3, :3]))):.3f} deg "
                  f"(approx. 1-sigma {math.degrees(sig[:3].max()):.3f} deg, {1000 * sig[3:].max():.2f} mm)")
    rows = [[n, f"{e:.3f}"] for n, e in res.per_pair_rms_px.items()] + [[n, f"skipped: {r}"] for n, r in res.skipped.items()]
    console.print(table("Per-pair reprojection RMS (px)", ["pair", "RMS px"], rows))
    console.print(f"stereo reprojection RMS {res.rms_px:.3f} px; wrote {args.out}")
    return 0
