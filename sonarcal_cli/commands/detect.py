"""``sonarcal detect SESSION``: find the sphere in every image and cloud, write detections.yaml."""

from __future__ import annotations

import numpy as np

from calib_core.detect.reasons import entry_note, score_text
from calib_core.errors import SessionError
from calib_core.detections import load_detections, save_detections
from calib_core.pipeline import SessionData, detect_session
from calib_core.session import load_session
from sonarcal_cli.ui import console, err_console, progress_bar, table


def add_parser(sub) -> None:
    p = sub.add_parser("detect", help="detect the sphere in every image and cloud; write detections.yaml")
    p.add_argument("session", help="session folder (holds session.yaml)")
    p.add_argument("--capture", action="append", metavar="ID", help="only this capture (repeatable)")
    p.add_argument("--missing-only", action="store_true", help="keep existing auto entries; detect only missing ones")
    p.add_argument("--force", action="store_true",
                   help="detect auto entries again even when their fingerprint (input files, detector, parameters) matches")
    p.add_argument("--nominal-beam", action="store_true",
                   help="fit clouds with session.yaml's beam width instead of estimating the effective one")
    p.set_defaults(run=run)


def _fmt_center(e: dict) -> str:
    c = e.get("center")
    if c is None:
        return "-"
    return "(" + ", ".join(f"{v:.4f}" if len(c) == 3 else f"{v:.1f}" for v in c) + (") m" if len(c) == 3 else ") px")


def run(args) -> int:
    session = load_session(args.session)
    existing = load_detections(session)
    if args.capture:
        unknown = set(args.capture) - {c.id for c in session.captures}
        if unknown:
            raise SessionError(session.manifest_path, f"no capture {', '.join(sorted(unknown))}")
    data = SessionData(session)
    with progress_bar("detecting") as cb:
        dets = detect_session(data, existing, progress=cb, captures=args.capture,
                              redetect_auto=not args.missing_only, estimate_beam_width=not args.nominal_beam,
                              reuse=not args.force)
    save_detections(session, dets)
    rows, missing = [], 0
    for cap in session.captures:
        for sensor in ["sonar", *cap.image_paths]:
            e = dets.get(cap.id, {}).get(sensor)
            if e is None:
                continue
            if e.get("center") is None and e.get("status") != "rejected":
                missing += 1
            seen = e.get("diameter_m") or e.get("apparent_diameter_m")
            rows.append([cap.id, sensor, e.get("status", ""), _fmt_center(e), score_text(e) or "-",
                         f"{seen * 1000:.0f} mm" if seen else "-", entry_note(e)])
    console.print(table(f"Detections ({session.name})", ["capture", "sensor", "status", "centre", "score",
                                                         "diameter seen", "reason"], rows))
    diams = [e["diameter_m"] for c in dets.values() for s, e in c.items() if s == "sonar" and e.get("diameter_m")]
    if len(diams) >= 3:
        med = float(np.median(diams))
        if abs(med / session.sphere_diameter_m - 1) > 0.1:
            err_console.print(f"warning: the sonar sees a {med * 1000:.0f} mm sphere but session.yaml says "
                              f"{session.sphere_diameter_m * 1000:.0f} mm: check sphere.diameter", markup=False)
    if data.beam_width_deg:
        console.print(f"sonar effective beam width {data.beam_width_deg:.3f} deg (session.yaml: {session.beam_width_deg:g} deg)")
    console.print(f"wrote {session.root / 'detections.yaml'}; {missing} detection(s) not found", markup=False)
    from calib_core.diagnose import diagnose_session

    notes: list[str] = []
    for f in diagnose_session(data, dets, notes):  # the workbench's flags, in the same words
        err_console.print(f"flag: {f.text}", markup=False)
    for note in notes:
        err_console.print(f"warning: {note}", markup=False)
    return 0
