"""Self-contained HTML report of a session and its calibration (``sonarcal report``).

One HTML file, no network: CSS inline, plots as inline SVG (:mod:`calib_core.report.svg`),
pictures as base64 data URIs (:mod:`calib_core.report.render`). Sections: session summary,
pose with 1- and 3-sigma uncertainty, the paper's Table I (when the calibration has
``table_i``), residual plots, every detection with a thumbnail and its status history,
segmentation overlays (Fig. 3) and coloured clouds (Figs. 4-5).

calibration.json is read defensively: only the spec's contract keys (``cameras.*.T_cam_sonar``)
are required; ``covariance``, ``residuals``, ``table_i``, ``range_scale``, ``warnings`` are
shown when present. Units in the report: mm and degrees.
"""

from __future__ import annotations

import datetime as _dt
import math
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from calib_core import __version__
from calib_core.camera import distortion_terms
from calib_core.detect.reasons import entry_note, score_phrase
from calib_core.errors import SessionError
from calib_core.markup import escape_html
from calib_core.report.captures import CaptureView, ReportOptions, calibrated_T, capture_view, range_scale
from calib_core.report.motion import motion_section
from calib_core.report.svg import bar_chart, scatter_residuals, sigma_chart

__all__ = ["ReportOptions", "build_report", "write_report"]

CSS = """
body{font-family:system-ui,sans-serif;margin:0 auto;max-width:1280px;padding:16px 24px;color:#222}
h1{font-size:1.6em}h2{border-bottom:2px solid #2b7bba;padding-bottom:4px;margin-top:2em}
table{border-collapse:collapse;margin:8px 0}td,th{border:1px solid #ccc;padding:3px 8px;font-size:13px;text-align:left}
th{background:#eef3f8}.num{text-align:right;font-variant-numeric:tabular-nums}.warn{color:#b35806}
.bad{color:#d7301f;font-weight:bold}.ok{color:#1b7837}.muted{color:#777}figure{display:inline-block;margin:6px}
figcaption{font-size:12px;color:#555}img{max-width:100%;border:1px solid #ccc}.hist{font-size:11px;margin:0;padding-left:14px}
.status-accepted,.status-corrected{color:#1b7837}.status-rejected{color:#d7301f}.status-auto{color:#555}
"""


def _e(x) -> str:
    return escape_html(x)


def _fmt(v, fmt: str = ".2f", none: str = "-") -> str:
    return none if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v) else format(v, fmt)


def _table(header: list[str], rows: list[list[str]], raw: bool = False) -> str:
    """An HTML table; cells are escaped unless ``raw``."""
    cell = (lambda c: str(c)) if raw else _e
    head = "".join(f"<th>{_e(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{cell(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


# ------------------------------------------------------------------ sections
def _summary(session, calibration, models, cal_note) -> str:
    rows = [["name", session.name], ["folder", str(session.root)], ["sphere diameter", f"{session.sphere_diameter_m * 1000:.1f} mm"],
            ["sonar", session.sonar_model or "-"], ["sound speed", f"{session.sound_speed_m_s} m/s" if session.sound_speed_m_s else "-"],
            ["beam width", f"{session.beam_width_deg:g} deg"], ["captures", str(len(session.captures))]]
    if session.measured_m:
        rows.append(["measured baselines", ", ".join(f"{k} {v * 1000:.1f} mm" for k, v in session.measured_m.items())])
    cams = [[c, f"{m.width_px} x {m.height_px}", f"{m.fx:.1f} / {m.fy:.1f}", f"{m.cx:.1f} / {m.cy:.1f}",
             f"{distortion_terms(m)}: " + " ".join(f"{d:.4g}" for d in m.dist)] if m else [c, "unavailable", "-", "-", "-"]
            for c, m in models.items()]
    html = _table(["", ""], rows) + _table(["camera", "size px", "fx / fy px", "cx / cy px", "distortion"], cams)
    if calibration:
        created = calibration.get("created") or "-"
        tool = calibration.get("tool") or {}
        html += (f"<p>Calibration: {_e(created)}; tool {_e(tool.get('name', '-'))} {_e(tool.get('version', ''))}; "
                 f"{_e(_scale_text(calibration))}</p>")
        from calib_core.solve.summary import consistency_lines

        html += "".join(f"<p>{_e(line)}</p>" for line in consistency_lines(calibration)
                        if line not in (calibration.get("warnings") or []))
        warnings = calibration.get("warnings") or []
        if warnings:
            html += "<ul>" + "".join(f'<li class="warn">{_e(w)}</li>' for w in warnings) + "</ul>"
    html += f'<p class="muted">{_e(cal_note)}</p>' if cal_note else ""
    return html


def _scale_text(calibration) -> str:
    from calib_core.solve.summary import scale_line

    s = calibration.get("range_scale")
    return scale_line(calibration) if isinstance(s, dict) else f"range scale {range_scale(calibration):g}"


def _pose(calibration) -> str:
    out = []
    for cam, c in (calibration.get("cameras") or {}).items():
        T = calibrated_T(calibration, cam)
        if T is None:
            continue
        t_mm = 1000 * T[:3, 3]
        rv = Rotation.from_matrix(T[:3, :3]).as_rotvec()
        sonar_in_cam = f"{np.linalg.norm(t_mm):.1f} mm"
        rows = [["translation t (mm)", " ".join(f"{v:.1f}" for v in t_mm)],
                ["rotation vector (deg)", " ".join(f"{v:.3f}" for v in np.degrees(rv))],
                ["rotation angle (deg)", f"{np.degrees(np.linalg.norm(rv)):.3f}"], ["|t| (sonar origin from camera)", sonar_in_cam],
                ["RMS reprojection (px)", _fmt(c.get("rms_reprojection_px"))],
                ["captures used", ", ".join(map(str, c.get("captures_used") or [])) or "-"],
                ["solution", str(c.get("solution", "-"))]]
        matrix = _table(["T_cam_sonar", "", "", ""], [[f"{v:.6f}" for v in row] for row in T])
        cov = c.get("covariance")
        sig_html = '<p class="muted">no covariance in calibration.json: uncertainty unknown</p>'
        try:
            C = np.asarray(cov, float)
            if C.shape == (6, 6) and np.isfinite(C).all():
                sd = np.sqrt(np.maximum(np.diag(C), 0))
                r1, t1 = np.degrees(sd[:3]), 1000 * sd[3:]
                rows += [["1-sigma rotation (deg) x y z", " ".join(f"{v:.3f}" for v in r1)],
                         ["3-sigma rotation (deg) x y z", " ".join(f"{3 * v:.3f}" for v in r1)],
                         ["1-sigma translation (mm) x y z", " ".join(f"{v:.1f}" for v in t1)],
                         ["3-sigma translation (mm) x y z", " ".join(f"{3 * v:.1f}" for v in t1)]]
                sig_html = (sigma_chart(f"{cam}: rotation sigma (1 / 3)", ["rot x", "rot y", "rot z"], list(r1), "deg")
                            + sigma_chart(f"{cam}: translation sigma (1 / 3)", ["t x", "t y", "t z"], list(t1), "mm"))
        except (TypeError, ValueError):
            pass
        out.append(f"<h3>{_e(cam)}</h3>{_table(['', ''], rows)}{matrix}<div>{sig_html}</div>")
    return "".join(out) or "<p>No camera has a calibrated pose.</p>"


def _table_i(calibration) -> str:
    tab = calibration.get("table_i")
    if not isinstance(tab, dict) or not isinstance(tab.get("pairs"), dict):
        return "<p class='muted'>No Table I in calibration.json (it needs two calibrated cameras).</p>"
    pairs = tab["pairs"]
    keys = list(pairs)

    def val(k, f, scale=1.0, fmt=".2f", suffix=""):
        v = (pairs.get(k) or {}).get(f)
        return _fmt(v * scale if isinstance(v, (int, float)) and not isinstance(v, bool) else None, fmt) + \
            (suffix if isinstance(v, (int, float)) else "")

    spec = [("Estimated length |t| (mm)", "estimated_m", 1000, ".2f", ""), ("  1-sigma (mm)", "estimated_sigma_m", 1000, ".2f", ""),
            ("Measured length (mm)", "measured_m", 1000, ".2f", ""), ("Error", "error_pct", 1, "+.2f", " %"),
            ("Assoc. length |t-hat| (mm)", "assoc_m", 1000, ".2f", ""), ("Assoc. error", "assoc_error_pct", 1, "+.2f", " %"),
            ("Error length |t - t-hat| (mm)", "error_length_m", 1000, ".2f", ""),
            ("Incl. angle (t, t-hat) (deg)", "included_angle_rad", 180 / math.pi, ".2f", "")]
    rows = [[name] + [val(k, f, sc, fm, sx) for k in keys] for name, f, sc, fm, sx in spec]
    note = f"<p class='muted'>{_e(tab.get('note'))}</p>" if tab.get("note") else ""
    return _table([""] + keys, rows) + note


def _residual_rows(calibration, cam, views: list[CaptureView]):
    """[(capture, du, dv, flagged)] from calibration.json's residuals, else recomputed here."""
    c = (calibration.get("cameras") or {}).get(cam) or {}
    rows = []
    for r in c.get("residuals") or []:
        try:
            du, dv = (float(v) for v in r["residual_px"])
            rows.append((str(r["capture"]), du, dv, not r.get("used", True) or bool(r.get("flags"))))
        except (KeyError, TypeError, ValueError):
            continue
    if rows:
        return rows, "from calibration.json"
    used = set(map(str, c.get("captures_used") or []))
    rows = [(v.id, *v.residual_px[cam], bool(used) and v.id not in used) for v in views if cam in v.residual_px]
    return rows, "recomputed from detections.yaml and T_cam_sonar"


def _residuals(calibration, views: list[CaptureView]) -> str:
    out = []
    for cam in calibration.get("cameras") or {}:
        rows, source = _residual_rows(calibration, cam, views)
        if not rows:
            out.append(f"<h3>{_e(cam)}</h3><p>No residuals (no capture has both detections).</p>")
            continue
        norms = [math.hypot(du, dv) for _, du, dv, _ in rows]
        rms = math.sqrt(sum(n * n for n in norms) / len(norms))
        out.append(f"<h3>{_e(cam)}</h3><p class='muted'>Reprojection residual (sonar centre projected minus image "
                   f"centre), {_e(source)}; red: left out or flagged.</p>"
                   + bar_chart(f"{cam}: residual per capture", [r[0] for r in rows], norms, "px", [r[3] for r in rows],
                               {f"RMS {rms:.2f} px": rms})
                   + scatter_residuals(f"{cam}: residual vectors (circles: 1 and 3 x RMS)", rows, sigma_px=rms,
                                       sigma_name="RMS"))
    return "".join(out) or "<p>No calibration.</p>"


def _history(entry: dict) -> str:
    hist = entry.get("history") if isinstance(entry, dict) else None
    if not isinstance(hist, list) or not hist:
        return ""
    items = []
    for h in hist:
        if not isinstance(h, dict):
            continue
        c = h.get("center")
        cs = " ".join(_fmt(v, ".4g") for v in c) if isinstance(c, list) else ""
        items.append(f"<li>{_e(h.get('time', ''))} <span class='status-{_e(h.get('status', ''))}'>{_e(h.get('status', ''))}"
                     f"</span> {_e(cs)} {_e(h.get('who', ''))}</li>")
    return f"<ul class='hist'>{''.join(items)}</ul>"


def _detections(session, detections, views: list[CaptureView]) -> str:
    sensors = ["sonar", *session.cameras]
    rows = []
    for v in views:
        row = [f"<b>{_e(v.id)}</b><br><span class='muted'>{v.n_points if v.n_points is not None else '?'} points</span>"]
        for s in sensors:
            e = (detections.get(v.id) or {}).get(s)
            st = e.get("status", "auto") if isinstance(e, dict) else "missing"
            c = e.get("center") if isinstance(e, dict) else None
            if s == "sonar" and isinstance(c, list):
                cs = "(" + ", ".join(f"{1000 * x:.0f}" for x in c) + ") mm"
            else:
                cs = "(" + ", ".join(f"{x:.1f}" for x in c) + ") px" if isinstance(c, list) else ""
            score = f" {score_phrase(e)}" if isinstance(e, dict) and score_phrase(e) else ""
            if isinstance(e, dict) and c is None and st != "rejected":
                score = f": {e.get('reason') or 'not found'}"  # a miss says why, not "score 0.00"
            thumb = f"<img src='{v.thumbs[s]}' alt='{_e(v.id)} {_e(s)}' width='160'><br>" if s in v.thumbs else ""
            res = v.residual_px.get(s)
            res_s = f"<br>residual {math.hypot(*res):.2f} px" if res else ""
            chosen = (f"<br><span class='muted'>{_e(entry_note(e))}</span>"
                      if isinstance(e, dict) and c is not None and e.get("resolved_by") else "")
            row.append(f"{thumb}<span class='status-{_e(st)}'>{_e(st)}</span> {_e(cs)}{_e(score)}{res_s}{chosen}"
                       + (_history(e) if isinstance(e, dict) else ""))
        row.append("<br>".join(f"<span class='bad'>{_e(p)}</span>" for p in v.problems))
        rows.append(row)
    return _table(["capture", *sensors, "problems"], rows, raw=True)


def _pictures(views: list[CaptureView]) -> tuple[str, str]:
    seg, col = [], []
    for v in views:
        for cam, uri in v.overlays.items():
            seg.append(f"<figure><img src='{uri}' alt='segmentation {_e(v.id)} {_e(cam)}' width='480'>"
                       f"<figcaption>{_e(v.id)} / {_e(cam)}</figcaption></figure>")
        if v.coloured_cloud:
            col.append(f"<figure><img src='{v.coloured_cloud}' alt='coloured cloud {_e(v.id)}' width='480'><figcaption>"
                       f"{_e(v.id)}: {100 * (v.coloured_fraction or 0):.0f} % of points coloured (orange: seen by no camera "
                       f"or hidden)</figcaption></figure>")
    return "".join(seg) or "<p>No overlays (needs a calibration and images).</p>", \
        "".join(col) or "<p>No coloured clouds (needs a calibration and images).</p>"


def _detections_from_calibration(calibration: dict | None) -> dict:
    """Detections rebuilt from calibration.json's per-capture residual rows (``uv_px``,
    ``X_sonar_m``), for sessions calibrated without a detections.yaml on disk."""
    out: dict = {}
    for cam, c in ((calibration or {}).get("cameras") or {}).items():
        for r in (c.get("residuals") or []) if isinstance(c, dict) else []:
            try:
                cid = str(r["capture"])
                uv = [float(v) for v in r["uv_px"]]
                X = [float(v) for v in r["X_sonar_m"]]
            except (KeyError, TypeError, ValueError):
                continue
            if len(uv) == 2 and len(X) == 3:
                out.setdefault(cid, {})[cam] = {"center": uv, "status": "auto"}
                out[cid].setdefault("sonar", {"center": X, "status": "auto"})
    return out


# ---------------------------------------------------------------------- page
def build_report(session, calibration: dict | None, detections: dict | None = None, progress=None,
                 options: ReportOptions | None = None, calibration_note: str = "") -> str:
    """The report's HTML text for ``session`` (a loaded Session) and a calibration dict (or None)."""
    opts = options or ReportOptions()
    from_cal = not detections and bool(_detections_from_calibration(calibration))
    detections = detections or _detections_from_calibration(calibration)
    models = {}
    problems = []
    for cam in session.cameras:
        try:
            models[cam] = session.camera_model(cam)
        except SessionError as e:
            models[cam] = None
            problems.append(str(e))
    views = []
    for k, cap in enumerate(session.captures):
        if progress:
            progress(k, len(session.captures), cap.id)
        views.append(capture_view(session, cap, detections, calibration, models, opts))
    if progress:
        progress(len(session.captures), len(session.captures), "writing")
    seg, col = _pictures(views)
    cal = calibration or {}
    now = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    body = [f"<h1>sonarcal report: {_e(session.name)}</h1><p class='muted'>generated {now} by sonarcal {_e(__version__)}</p>",
            "<h2>Session</h2>", _summary(session, calibration, models, calibration_note),
            "".join(f"<p class='bad'>{_e(p)}</p>" for p in problems)]
    if calibration:
        body += ["<h2>Pose (T_cam_sonar) and uncertainty</h2><p class='muted'>T_cam_sonar maps sonar-frame points "
                 "into the camera's OpenCV frame (x right, y down, z forward); t is the sonar origin seen from the "
                 "camera. Sigmas: square roots of the covariance diagonal (rotation vector, translation).</p>",
                 _pose(cal), "<h2>Table I: baselines</h2>", _table_i(cal), "<h2>Residuals</h2>", _residuals(cal, views)]
    body += ["<h2>Detections</h2><p class='muted'>Image thumbnails: detected ellipse (yellow), detected centre (red "
             "cross), reprojected sonar centre (cyan). Sonar thumbnails: points within 3 radii of the detected centre, "
             "coloured by range, with the sphere outline.</p>",
             "<p class='warn'>No detections.yaml: showing the detections calibration.json used (no status history; "
             "run 'sonarcal detect' or review in the workbench to record them).</p>" if from_cal else
             "" if detections else "<p class='warn'>No detections.yaml yet: run 'sonarcal detect' (or review in the "
                                   "workbench) to record detections and their status history.</p>",
             _detections(session, detections, views), motion_section(session),
             "<h2>Segmentation by the reprojected cloud (paper Fig. 3)</h2>", seg,
             "<h2>Cloud coloured from the images (paper Figs. 4-5)</h2>", col]
    return (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>sonarcal report: {_e(session.name)}</title>"
            f"<meta name='viewport' content='width=device-width, initial-scale=1'><style>{CSS}</style></head><body>"
            + "\n".join(body) + "</body></html>\n")


def write_report(session, out_path: str | Path, calibration: dict | None, detections: dict | None = None,
                 progress=None, options: ReportOptions | None = None, calibration_note: str = "") -> Path:
    """Build the report and write it atomically to ``out_path``; returns the path."""
    from calib_core.io.atomic import atomic_write_text

    from calib_core.io.confine import confine_write

    confine_write(session.root, out_path, explicit=True)  # inside the session: no symlink out of it
    html = build_report(session, calibration, detections, progress, options, calibration_note)
    atomic_write_text(out_path, html)
    return Path(out_path)
