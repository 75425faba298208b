"""``sonarcal synth OUT --preset NAME --seed N [--force] [--scale S]``: write a synthetic
session with ground truth (``ground_truth.yaml``) into folder OUT."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

from sonarcal_cli.ui import console, err_console, progress_bar

GENERATED = ("session.yaml", "ground_truth.yaml", "detections.yaml", "images", "clouds", "backgrounds",
             "intrinsics", "results", "frames")


def add_parser(sub) -> None:
    from calib_core.synth.presets import PRESETS

    p = sub.add_parser("synth", help="generate a synthetic session with ground truth",
                       description="Generate a synthetic session (images, sonar clouds, intrinsics, "
                                   "backgrounds) plus ground_truth.yaml. Presets: "
                                   + "; ".join(f"{k}: {v.description}" for k, v in PRESETS.items()))
    p.add_argument("out", help="output session folder (created; must be empty unless --force)")
    p.add_argument("--preset", default="quick", help=f"scene preset ({', '.join(PRESETS)}); default quick")
    p.add_argument("--seed", type=int, default=1, help="random seed (varies rig, intrinsics, positions, noise)")
    p.add_argument("--scale", type=float, default=None,
                   help="image resolution factor (1 = 1920x1080; e.g. 0.25 for fast tests)")
    p.add_argument("--force", action="store_true", help="replace the contents of a non-empty OUT folder")
    p.add_argument("--bag", choices=["ros2", "ros2-db3", "ros1"],
                   help="also write the session as a ROS bag recorded over time (ros2: MCAP folder OUT_ros2; "
                        "ros2-db3: SQLite folder OUT_db3; ros1: OUT.bag); import it with sonarcal import")
    p.add_argument("--bag-path", help="where to write the bag (must not exist)")
    p.set_defaults(run=run)


def run(args) -> int:
    from calib_core.synth.generate import generate_session
    from calib_core.synth.presets import PRESETS

    if args.preset not in PRESETS:
        err_console.print(f"error: unknown preset '{args.preset}'. Presets:", markup=False)
        for k, v in PRESETS.items():
            err_console.print(f"  {k:<11} {v.description}", markup=False)
        return 2
    if args.scale is not None and not 0.05 <= args.scale <= 2.0:
        print(f"error: --scale {args.scale} is outside 0.05-2.0", file=sys.stderr)
        return 2
    out = Path(args.out)
    bag = _bag_path(out, args) if args.bag else None
    if bag is not None and bag.exists():
        print(f"error: {bag}: bag path exists already (remove it or give --bag-path)", file=sys.stderr)
        return 2
    if out.exists() and not out.is_dir():
        print(f"error: {out}: exists and is not a folder", file=sys.stderr)
        return 2
    if out.is_dir() and any(out.iterdir()):
        if not args.force:
            print(f"error: {out}: folder is not empty (use --force to replace its contents)", file=sys.stderr)
            return 2
        # remove only what a generated session holds (never unrelated files of the folder)
        for name in GENERATED:
            child = out / name
            if child.is_dir() and not child.is_symlink():
                shutil.rmtree(child)
            elif child.exists() or child.is_symlink():
                child.unlink()
    overrides = {} if args.scale is None else {"scale": args.scale}
    with progress_bar(f"synth {args.preset}") as cb:
        generate_session(out, args.preset, args.seed, progress=cb, **overrides)
    console.print(f"wrote session {out} (preset {args.preset}, seed {args.seed}) with ground_truth.yaml", markup=False)
    if bag is not None:
        _write_bag(out, bag, args)
    return 0


def _bag_path(out: Path, args) -> Path:
    default = {"ros2": f"{out}_ros2", "ros2-db3": f"{out}_db3", "ros1": f"{out}.bag"}[args.bag]
    return Path(args.bag_path or default)


def _write_bag(out: Path, path: Path, args) -> None:
    from calib_core.synth.bag import BACKGROUND_S, write_session_bag

    with progress_bar(f"bag {args.bag}") as cb:
        write_session_bag(out, path, args.bag, seed=args.seed, progress=cb)
    console.print(f"wrote {args.bag} bag {path} (background frames in the first {BACKGROUND_S:g} s: "
                  f"import with --background 0:{BACKGROUND_S:g})", markup=False)
