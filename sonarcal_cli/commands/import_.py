"""``sonarcal import SOURCE --out SESSION --diameter D``: a session from a ROS 1 / ROS 2 bag, or
from a video plus a CSV of scan times (``--scans``), with a target-motion check per scan."""

from __future__ import annotations

from pathlib import Path

from calib_core.errors import SessionError
from sonarcal_cli.ui import console, err_console, progress_bar, table

VIDEO_SUFFIXES = (".mp4", ".avi", ".mkv", ".mov", ".m4v", ".webm")


def add_parser(sub) -> None:
    from calib_core.ingest.motion import TOLERANCE_M, TOLERANCE_PX

    p = sub.add_parser("import", help="make a session from a ROS bag, or a video plus scan times",
                       description="Write a session folder from a ROS 1 .bag, a ROS 2 bag (.db3/.mcap or its "
                                   "folder), or a video file with a CSV of scan times (--scans). Each sonar scan "
                                   "becomes a capture with the camera frame from the middle of the scan; the "
                                   "sphere is tracked through the scan's frames and a capture whose target moved "
                                   "is flagged.")
    p.add_argument("source", help="bag file or folder, or a video file")
    p.add_argument("--out", help="new session folder (must not exist, or be empty)")
    p.add_argument("--list", action="store_true", help="list the bag's topics, types and message counts, then stop")
    p.add_argument("--diameter", type=float, help="sphere diameter in metres (required to import)")
    p.add_argument("--sonar-topic", help="PointCloud2 topic of the sonar (default: the only one)")
    p.add_argument("--camera-topic", action="append", metavar="[NAME=]TOPIC",
                   help="image topic of a camera (repeat for several; default: every image topic)")
    p.add_argument("--intrinsics", action="append", metavar="[NAME=]FILE", default=[],
                   help="intrinsics file for a camera instead of its CameraInfo (needed for a video): ROS "
                        "camera_info YAML, OpenCV FileStorage or a Kalibr camchain")
    p.add_argument("--intrinsics-entry", action="append", metavar="[NAME=]ENTRY", default=[],
                   help="which entry of a Kalibr camchain given with --intrinsics is this camera (e.g. cam0); "
                        "as session.yaml's intrinsics_entry")
    p.add_argument("--split", default="auto", choices=["auto", "gap", "message"],
                   help="how the sonar stream is cut into scans (default auto)")
    p.add_argument("--gap-seconds", type=float, help="a pause longer than this ends a scan")
    p.add_argument("--scan-seconds", type=float, help="cut the sonar stream into scans this long")
    p.add_argument("--background", metavar="START:END",
                   help="seconds from the start with the sphere out of view: background frames")
    p.add_argument("--scans", help="video input: CSV with columns id,start_s,end_s,cloud (seconds into the video)")
    p.add_argument("--camera", default="cam1", help="video input: camera name (default cam1)")
    p.add_argument("--tolerance-px", type=float, default=TOLERANCE_PX,
                   help=f"flag a capture whose sphere moved more pixels than this (default {TOLERANCE_PX})")
    p.add_argument("--tolerance-m", type=float, default=TOLERANCE_M,
                   help=f"... or more metres across the view than this (default {TOLERANCE_M})")
    p.add_argument("--drop-moved", action="store_true", help="leave flagged captures out of the session")
    p.add_argument("--median", type=int, default=1, metavar="N",
                   help="write the pixel-wise median of the N frames nearest mid-scan (still targets only; "
                        "default 1: the mid-scan frame)")
    p.add_argument("--name", help="session name (default: the source's name)")
    p.add_argument("--sonar-model", help="sonar model text for session.yaml")
    p.set_defaults(run=run)


def run(args) -> int:
    source = Path(args.source)
    if args.list:
        return _list(source)
    if not args.out or args.diameter is None:
        raise SessionError(source, "give --out SESSION and --diameter METRES (or --list to see the topics)")
    if not 0.01 <= args.diameter <= 5:
        raise SessionError(None, f"--diameter {args.diameter} m is outside 0.01-5 m")
    opts = _options(args)
    with progress_bar(f"import {source.name}") as cb:
        if source.suffix.lower() in VIDEO_SUFFIXES:
            from calib_core.ingest.video import import_video

            if not args.scans:
                raise SessionError(source, "a video needs --scans CSV (id,start_s,end_s,cloud) and --intrinsics FILE")
            res = import_video(source, Path(args.scans), args.camera, args.out, opts, progress=cb)
        else:
            from calib_core.ingest.importer import import_bag

            res = import_bag(source, args.out, opts, progress=cb)
    console.print(f"wrote session {res.out}: {len(res.captures)} captures ({', '.join(res.captures)})", markup=False)
    if res.skipped:
        console.print(f"skipped scans: {', '.join(res.skipped)} (see source.captures in session.yaml)", markup=False)
    if res.moved:
        what = "left out" if args.drop_moved else "kept; check them or use --drop-moved"
        console.print(f"TARGET MOVED during scan: {', '.join(res.moved)} (more than {opts.tolerance_px} px or "
                      f"{opts.tolerance_m * 1000:.0f} mm; {what})", markup=False)
    return 0


def _options(args):
    from calib_core.ingest.assemble import ImportOptions

    intr = {}
    for item in args.intrinsics:
        name, _, path = item.rpartition("=")
        intr[name or args.camera] = Path(path)
    entries = {}
    for item in args.intrinsics_entry:
        name, _, entry = item.rpartition("=")
        name = name or args.camera
        if name not in intr or not entry:
            raise SessionError(None, f"--intrinsics-entry {item!r}: give it as NAME=ENTRY for a camera "
                                     f"that has --intrinsics NAME=FILE")
        entries[name] = entry
    window = None
    if args.background:
        try:
            a, b = (float(x) for x in args.background.split(":"))
        except ValueError:
            raise SessionError(None, f"--background {args.background!r}: expected START:END in seconds") from None
        window = (a, b)
    if not 1 <= args.median <= 25:
        raise SessionError(None, f"--median {args.median}: use 1-25 frames")
    for flag in ("gap_seconds", "scan_seconds"):
        v = getattr(args, flag)
        if v is not None and not v > 0:
            raise SessionError(None, f"--{flag.replace('_', '-')} must be positive")
    return ImportOptions(diameter_m=args.diameter, sonar_topic=args.sonar_topic, camera_topics=args.camera_topic,
                         intrinsics=intr, intrinsics_entry=entries, split=args.split, gap_seconds=args.gap_seconds,
                         scan_seconds=args.scan_seconds, background_window_s=window, tolerance_px=args.tolerance_px,
                         tolerance_m=args.tolerance_m, drop_moved=args.drop_moved, median=args.median, name=args.name,
                         sonar_model=args.sonar_model)


def _list(source: Path) -> int:
    from calib_core.ingest.bag import list_topics, open_bag

    with open_bag(source) as reader:
        rows = list_topics(reader)
        dur = (reader.end_time - reader.start_time) / 1e9 if rows else 0.0
    console.print(table(f"{source} ({dur:.1f} s)", ["topic", "type", "messages"],
                        [[r.topic, r.msgtype, r.count] for r in rows]))
    if not rows:
        err_console.print("the bag holds no topics")
    return 0
