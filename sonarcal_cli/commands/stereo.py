"""``sonarcal stereo FOLDER1 FOLDER2``: stereo transform T_cam2_cam1 from simultaneous checkerboard images."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from rich.markup import escape

from calib_core.errors import SessionError
from sonarcal_cli.checkerboard_common import check_square, load_images
from sonarcal_cli.ui import console, progress_bar, table


def add_parser(sub) -> None:
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


def run_stereo(args) -> int:
    from calib_core.io.atomic import atomic_write_yaml
    from calib_core.io.intrinsics import load_intrinsics
    from calib_core.solve.checkerboard import calibrate_intrinsics, calibrate_stereo, pair_folders, parse_pattern
    from calib_core.solve.model import log_so3

    pattern = parse_pattern(args.pattern)
    check_square(args.square)
    n1, n2 = args.names
    pairs = pair_folders(args.folder1, args.folder2)
    loaded = [(n, a, b) for (n, a), (_, b) in zip(load_images([(n, p) for n, p, _ in pairs]), load_images([(n, p) for n, _, p in pairs]))]
    cams = []
    for which, path, folder, idx in ((n1, args.intrinsics1, args.folder1, 1), (n2, args.intrinsics2, args.folder2, 2)):
        if path:
            cams.append(load_intrinsics(path, which))
        else:
            imgs = [(t[0], t[idx]) for t in loaded]
            with progress_bar(f"{which} intrinsics") as cb:
                try:
                    r = calibrate_intrinsics(imgs, pattern, args.square, name=which, progress=cb)
                except SessionError as e:
                    raise SessionError(e.path or Path(folder), e.problem) from None
            console.print(f"{which}: intrinsics from {folder} (RMS {r.rms_px:.3f} px; give --intrinsics{idx} to use a file)", markup=False)
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
    console.print(f"[bold]{escape(key)}[/bold]: baseline {1000 * np.linalg.norm(T[:3, 3]):.1f} mm, rotation "
                  f"{math.degrees(np.linalg.norm(log_so3(T[:3, :3]))):.3f} deg "
                  f"(approx. 1-sigma {math.degrees(sig[:3].max()):.3f} deg, {1000 * sig[3:].max():.2f} mm)")
    rows = [[n, f"{e:.3f}"] for n, e in res.per_pair_rms_px.items()] + [[n, f"skipped: {r}"] for n, r in res.skipped.items()]
    console.print(table("Per-pair reprojection RMS (px)", ["pair", "RMS px"], rows))
    console.print(f"stereo reprojection RMS {res.rms_px:.3f} px; wrote {args.out}", markup=False)
    return 0
