"""``sonarcal plan SESSION [--count 3] [--target 0.1deg,5mm]``: where to put the sphere next, and
whether the target precision is met (exit 0 either way; 2 on bad input)."""

from __future__ import annotations

from sonarcal_cli.ui import console, progress_bar, table


def add_parser(sub) -> None:
    p = sub.add_parser("plan", help="suggest where the next sphere captures should go, and say when to stop")
    p.add_argument("session", help="session folder (holds session.yaml)")
    p.add_argument("--count", type=int, default=3, help="number of suggestions (default 3)")
    p.add_argument("--target", default="0.1deg,5mm",
                   help="target 1-sigma per axis, rotation and translation (default 0.1deg,5mm)")
    p.add_argument("--criterion", choices=["worst", "d"], default="worst",
                   help="worst (default): smallest worst-axis 1-sigma relative to the target; "
                        "d: D-optimal (log det of the pose information)")
    p.add_argument("--range", dest="working_range", default=None,
                   help="working range of the sphere from the sonar, metres, e.g. 1,4 "
                        "(default: the captures' ranges widened by 25 %%)")
    p.set_defaults(run=run)


def _range(text: str | None):
    from calib_core.errors import SessionError

    if text is None:
        return None
    try:
        a, b = (float(v) for v in text.split(","))
    except ValueError:
        raise SessionError(None, f"--range {text!r}: give two distances in metres, e.g. 1,4") from None
    if not 0 <= a < b:
        raise SessionError(None, f"--range {text!r}: the first distance must be below the second")
    return a, b


def run(args) -> int:
    from calib_core.detections import load_detections
    from calib_core.errors import SessionError
    from calib_core.plan.report import plan_lines, suggestion_rows
    from calib_core.plan.session_plan import plan_session
    from calib_core.plan.target import parse_target
    from calib_core.results import calibration_path, load_calibration
    from calib_core.session import load_session

    if not 1 <= args.count <= 20:
        raise SessionError(None, f"--count {args.count}: give 1 to 20 suggestions")
    try:
        target = parse_target(args.target)
    except ValueError as e:
        raise SessionError(None, f"--target: {e}") from None
    wr = _range(args.working_range)
    session = load_session(args.session)
    # as calibrate does: entries an operator validated are used as written, auto entries whose
    # fingerprint still matches are reused, and what is missing is detected (not saved)
    from calib_core.pipeline import detect_session

    with progress_bar("detect") as cb:
        detections = detect_session(session, load_detections(session), progress=cb)
    cal_path = calibration_path(session)
    calibration = load_calibration(cal_path) if cal_path.is_file() else None
    sp = plan_session(session, detections, calibration, target, None, args.count, args.criterion, working_range_m=wr)
    for line in plan_lines(sp):
        console.print(line, markup=False)
    cols, rows = suggestion_rows(sp.plan, sp.field, sp.cameras)
    if rows:
        console.print(table("Next sphere positions (sonar frame; pixels are the sphere centre, r its outline radius)",
                            cols, rows))
    return 0

