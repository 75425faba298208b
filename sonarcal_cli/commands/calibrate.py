"""``sonarcal calibrate SESSION [--out FILE]``: solve every camera, write calibration.json, print a report."""

from __future__ import annotations

from pathlib import Path

from sonarcal_cli.ui import console, err_console, progress_bar, table


def add_parser(sub) -> None:
    p = sub.add_parser("calibrate", help="calibrate every camera to the sonar and write results/calibration.json")
    p.add_argument("session", help="session folder (holds session.yaml)")
    p.add_argument("--out", default=None, help="output file (default SESSION/results/calibration.json)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--scale", dest="scale", action="store_const", const=True, default=None,
                   help="estimate the sonar range scale whenever observable, even when the test finds no scale error "
                        "(default: estimated when observable and the data show a scale error)")
    g.add_argument("--no-scale", dest="scale", action="store_const", const=False,
                   help="hold the sonar range scale at 1")
    p.add_argument("--robust", choices=["huber", "cauchy"], default=None, help="robust loss on each capture")
    p.add_argument("--no-detect", action="store_true",
                   help="do not run the detectors: use the entries in detections.yaml as they are")
    p.add_argument("--no-loo", action="store_true", help="skip the leave-one-out residuals")
    p.add_argument("--quiet", action="store_true", help="print only the pose summary")
    p.set_defaults(run=run)


def run(args) -> int:
    from calib_core.detections import load_detections
    from calib_core.errors import SessionError
    from calib_core.results import calibration_path, save_calibration
    from calib_core.session import load_session
    from calib_core.solve.calibrate import calibrate_session

    session = load_session(args.session)
    detections = load_detections(session)
    out = Path(args.out) if args.out else calibration_path(session)
    from calib_core.io.confine import confine_write

    confine_write(session.root, out, explicit=bool(args.out))  # refuse before the solve, not after
    if out.is_dir():
        raise SessionError(out, "--out is a folder; give a file name such as calibration.json")
    opts = {"estimate_scale": args.scale, "robust": args.robust, "detect": not args.no_detect,
            "leave_one_out": not args.no_loo}
    with progress_bar("calibrate") as cb:
        cal = calibrate_session(session, detections, opts, progress=cb)
    save_calibration(out, cal, root=session.root, explicit=bool(args.out))
    print_report(cal, quiet=args.quiet)
    console.print(f"wrote {out}", markup=False)
    return 0


def print_report(cal: dict, quiet: bool = False) -> None:
    from calib_core.detect.reasons import count_reasons
    from calib_core.solve.summary import consistency_lines, pose_rows, residual_rows, scale_line, table_i_rows

    console.print(f"Calibration of {cal['session']}", style="bold", markup=False)  # the name is the user's text
    cols, rows = pose_rows(cal)
    console.print(table("T_cam_sonar per camera (sonar origin in the camera frame; sigmas about camera axes)", cols, rows))
    console.print(scale_line(cal), markup=False)
    for line in consistency_lines(cal):
        if line not in cal.get("warnings", []):
            console.print(line, markup=False)
    if quiet:
        return
    for cam in cal["cameras"]:
        cols, rows = residual_rows(cal, cam)
        console.print(table(f"{cam}: per-capture residuals (independent solve)", cols, rows))
        for o in cal["cameras"][cam].get("outliers", []):
            for why in o["reasons"]:
                console.print(f"  {cam} {o['capture']}: {why}", style="yellow", markup=False)
    for cam, c in (cal.get("cameras") or {}).items():
        skipped = c.get("skipped") or {}
        if skipped:
            console.print(f"{cam}: {len(skipped)} capture(s) not used: {count_reasons(skipped.values())}",
                          style="yellow", markup=False)
    ti = table_i_rows(cal)
    if ti:
        console.print(table("Table I (independent solves; lengths in mm)", *ti))
    for w in cal.get("warnings", []):
        err_console.print(f"warning: {w}", style="yellow", markup=False)
