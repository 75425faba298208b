"""``sonarcal export SESSION --format F``: the calibration in a format for ROS, Kalibr, URDF, ..."""

from __future__ import annotations

import sys
from pathlib import Path

from calib_core.errors import SessionError
from calib_core.export import FORMATS, NEEDS_INTRINSICS, FrameNames, export_text
from calib_core.io.atomic import atomic_write_text
from calib_core.io.confine import confine_write
from calib_core.results import calibration_path, load_calibration
from calib_core.session import load_session


def add_parser(sub) -> None:
    p = sub.add_parser("export", help="export the calibration (JSON, ROS tf, URDF, Kalibr, camera_info)")
    p.add_argument("session", help="session folder (holds session.yaml and results/calibration.json)")
    p.add_argument("--format", required=True, choices=FORMATS, help="output format")
    p.add_argument("--camera", default=None, help="only this camera (camera-info needs one when there are several)")
    p.add_argument("--out", default=None, help="write to FILE instead of printing")
    p.add_argument("--calibration", default=None, help="calibration.json to read (default SESSION/results/calibration.json)")
    p.add_argument("--parent", choices=("sonar", "camera"), default="sonar",
                   help="parent frame of the published ROS transforms (default sonar: camera pose in the sonar frame)")
    p.add_argument("--sonar-frame", default="sonar", help="ROS name of the sonar frame (default sonar)")
    p.add_argument("--camera-frame", default="{cam}_optical_frame",
                   help="ROS name of a camera frame, {cam} = camera name (default {cam}_optical_frame)")
    p.set_defaults(run=run)


def run(args) -> int:
    session = load_session(args.session)
    cal_path = Path(args.calibration) if args.calibration else calibration_path(session)
    calibration = load_calibration(cal_path)
    if "{cam}" not in args.camera_frame and not args.camera and len(calibration["cameras"]) > 1:
        raise SessionError(cal_path, "--camera-frame must contain {cam} when several cameras are exported")
    intrinsics = None
    if args.format in NEEDS_INTRINSICS:
        wanted = [args.camera] if args.camera else list(calibration["cameras"] if args.format == "kalibr" else session.cameras)
        for cam in wanted:
            if cam not in session.cameras:
                raise SessionError(session.manifest_path, f"no camera '{cam}' in the session (cameras: {', '.join(session.cameras)})")
        intrinsics = {cam: session.camera_model(cam) for cam in wanted}
    frames = FrameNames(sonar=args.sonar_frame, camera_pattern=args.camera_frame, parent=args.parent)
    try:
        text = export_text(calibration, args.format, camera=args.camera, intrinsics=intrinsics, frames=frames)
    except KeyError as e:
        raise SessionError(cal_path, str(e.args[0])) from None
    except ValueError as e:
        raise SessionError(cal_path, str(e)) from None
    if args.out:
        confine_write(session.root, args.out, explicit=True)
        atomic_write_text(args.out, text)
        print(f"wrote {args.out} ({args.format})", file=sys.stderr)
    else:
        sys.stdout.write(text)
    return 0
