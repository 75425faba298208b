"""``sonarcal intrinsics FOLDER``: camera intrinsics from checkerboard images (ROS camera_info YAML)."""

from __future__ import annotations

from pathlib import Path

from rich.markup import escape

from calib_core.camera import distortion_terms
from calib_core.errors import SessionError
from sonarcal_cli.checkerboard_common import check_square, load_images
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


def run_intrinsics(args) -> int:
    from calib_core.io.intrinsics import save_intrinsics_ros
    from calib_core.solve.checkerboard import calibrate_intrinsics, folder_images, parse_pattern

    pattern = parse_pattern(args.pattern)
    check_square(args.square)
    out = Path(args.out)
    name = args.name or out.stem
    images = load_images(folder_images(args.folder))
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
    console.print(f"distortion {distortion_terms(c)}: " + " ".join(f"{v:.5f}" for v in c.dist))
    rows = [[n, f"{e:.3f}"] for n, e in res.per_image_rms_px.items()]
    rows += [[n, f"skipped: {r}"] for n, r in res.skipped.items()]
    console.print(table(f"Per-image reprojection RMS (px), {len(res.per_image_rms_px)} used", ["image", "RMS px"], rows))
    console.print(f"reprojection RMS {res.rms_px:.3f} px; wrote {out}", markup=False)
    return 0
