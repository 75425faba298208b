"""``sonarcal report SESSION [--out FILE]``: a self-contained HTML report (default results/report.html)."""

from __future__ import annotations

from pathlib import Path

from calib_core.detections import load_detections
from calib_core.results import calibration_path, load_calibration
from calib_core.session import load_session
from sonarcal_cli.ui import console, progress_bar


def add_parser(sub) -> None:
    p = sub.add_parser("report", help="write a self-contained HTML report of the session and its calibration")
    p.add_argument("session", help="session folder (holds session.yaml)")
    p.add_argument("--out", default=None, help="HTML file to write (default SESSION/results/report.html)")
    p.add_argument("--calibration", default=None, help="calibration.json to read (default SESSION/results/calibration.json)")
    p.add_argument("--mask-radius", type=float, default=None, help="segmentation radius in px (default 0.6 %% of the image width)")
    p.set_defaults(run=run)


def run(args) -> int:
    from calib_core.report import ReportOptions, write_report  # lazy: scipy and cv2 slow every CLI start

    session = load_session(args.session)
    detections = load_detections(session)
    cal_path = Path(args.calibration) if args.calibration else calibration_path(session)
    calibration, note = None, ""
    if cal_path.exists() or args.calibration:
        calibration = load_calibration(cal_path)  # a corrupt file is an error, not a silent omission
    else:
        note = f"No calibration yet ({cal_path} does not exist): run 'sonarcal calibrate' for poses and overlays."
    out = Path(args.out) if args.out else session.root / "results" / "report.html"
    opts = ReportOptions(mask_radius_px=args.mask_radius)
    with progress_bar("report") as cb:
        write_report(session, out, calibration, detections, progress=cb, options=opts, calibration_note=note)
    if note:
        console.print(note, style="yellow", markup=False)  # holds a path: '[' in a folder name is not markup
    console.print(f"wrote {out}", markup=False)
    return 0
