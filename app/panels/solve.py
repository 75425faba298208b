"""Solve panel: run calib_core's solver in a worker thread, then show what it returned.

The workbench saves exactly the dict ``calibrate_session`` returns (via
calib_core.results.save_calibration), so the browser and ``sonarcal calibrate`` agree.
"""

from __future__ import annotations

import cv2
import numpy as np

from app.common import guarded, notify
from calib_core.markup import escape_md
from calib_core.solve.summary import consistency_lines, pose_rows, residual_rows, scale_line, table_i_rows

BAR_RGB = [(255, 120, 0), (0, 150, 150), (150, 60, 220), (120, 120, 0)]


def capture_residuals(cal: dict) -> dict[str, list[dict]]:
    """{camera: [per-capture rows with capture, residual_norm_px, used, flags]} from a calibration."""
    out = {}
    for cam, c in (cal or {}).get("cameras", {}).items():
        rows = c.get("residuals") or []
        if isinstance(rows, dict):
            rows = [dict(v, capture=k) for k, v in rows.items()]
        out[cam] = [r for r in rows if isinstance(r, dict) and "capture" in r]
    return out


def residual_plot(cal: dict, width: int = 400, height: int = 270) -> np.ndarray | None:
    """Bar chart (RGB image) of each capture's reprojection residual (px), per camera;
    captures the solver left out or flagged are drawn hatched red."""
    rows = capture_residuals(cal)
    caps = []
    for rs in rows.values():
        for r in rs:
            if r["capture"] not in caps:
                caps.append(r["capture"])
    if not caps:
        return None
    vals = {cam: {r["capture"]: r for r in rs} for cam, rs in rows.items()}
    vmax = max([float(r.get("residual_norm_px") or 0) for rs in rows.values() for r in rs] + [1.0])
    img = np.full((height, width, 3), 255, np.uint8)
    left, bottom, top = 50, 58, 30
    ph = height - bottom - top
    gw = (width - left - 10) / len(caps)
    bw = gw * 0.8 / max(len(rows), 1)
    font, fs = cv2.FONT_HERSHEY_SIMPLEX, 0.5  # drawn near the panel's width: ~10 px tall text on screen
    for k in range(5):
        y = int(top + ph - ph * k / 4)
        cv2.line(img, (left, y), (width - 10, y), (225, 225, 225), 1)
        cv2.putText(img, f"{vmax * k / 4:.1f}", (4, y + 5), font, fs, (40, 40, 40), 1, cv2.LINE_AA)
    cv2.putText(img, "residual px (red: left out / flagged)", (4, 20), font, fs, (0, 0, 0), 1, cv2.LINE_AA)
    for i, cid in enumerate(caps):
        x0 = left + i * gw + gw * 0.1
        for j, cam in enumerate(rows):
            r = vals[cam].get(cid)
            if r is None or r.get("residual_norm_px") is None:
                continue
            h = ph * min(float(r["residual_norm_px"]) / vmax, 1.0)
            p0 = (int(x0 + j * bw), int(top + ph - h))
            p1 = (int(x0 + (j + 1) * bw - 2), int(top + ph))
            bad = (not r.get("used", True)) or bool(r.get("flags"))
            cv2.rectangle(img, p0, p1, (220, 40, 40) if bad else BAR_RGB[j % len(BAR_RGB)], -1)
        cv2.putText(img, str(cid)[:6], (int(x0), height - bottom + 20 + 20 * (i % 2)), font, fs, (0, 0, 0), 1,
                    cv2.LINE_AA)
    for j, cam in enumerate(rows):
        x = width - 70 * (len(rows) - j)
        cv2.rectangle(img, (x, height - 16), (x + 12, height - 4), BAR_RGB[j % len(BAR_RGB)], -1)
        cv2.putText(img, cam, (x + 16, height - 4), font, fs, (0, 0, 0), 1, cv2.LINE_AA)
    return img


def md_table(cols, rows) -> str:
    """A markdown table (every cell escaped)."""
    esc = escape_md  # names and texts from files: no markup reaches the page
    out = ["| " + " | ".join(esc(c) for c in cols) + " |", "|" + "---|" * len(cols)]
    out += ["| " + " | ".join(esc(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def describe(cal: dict, flags=()) -> str:
    """Markdown: the CLI's tables (calib_core.solve.summary): pose and uncertainty per camera
    (transposed to fit the panel), range scale, per-capture residuals, outliers, Table I."""
    if not cal:
        return "No calibration yet: press **Solve**."
    try:
        return _describe_full(cal, flags)
    except (KeyError, TypeError, ValueError, IndexError):  # a calibration.json with the contract's keys only
        return _describe_minimal(cal)


def _describe_minimal(cal: dict) -> str:
    out = ["**Pose T_cam_sonar** (from results/calibration.json; it lacks this tool's uncertainty tables)", ""]
    for cam, c in cal.get("cameras", {}).items():
        T = np.asarray(c.get("T_cam_sonar"), float)
        t_mm = " ".join(f"{v:.1f}" for v in 1000 * T[:3, 3]) if T.shape == (4, 4) else "?"
        rms = c.get("rms_reprojection_px")
        out.append(f"- {escape_md(cam)}: t (mm) {t_mm}" + (f"; RMS {rms:.2f} px" if isinstance(rms, (int, float)) else ""))
    return "\n".join(out)


def _describe_full(cal: dict, flags=()) -> str:
    cols, rows = pose_rows(cal)
    out = ["**Pose T_cam_sonar** (sonar origin in the camera frame)", "",
           md_table(["", *[r[0] for r in rows]], [[c, *[r[i] for r in rows]] for i, c in enumerate(cols) if i > 0]),
           "", f"**Range scale**: {escape_md(scale_line(cal))}"]
    out += ["", *[f"**Consistency**: {escape_md(line)}" for line in consistency_lines(cal)
                  if line not in (cal.get("warnings") or [])]]
    for cam in cal["cameras"]:
        cols, rows = residual_rows(cal, cam)
        keep = [cols.index(c) for c in ("capture", "used", "residual px", "Mahalanobis", "flags")]
        out += ["", f"**{escape_md(cam)}: residuals per capture**", "", md_table([cols[i] for i in keep], [[r[i] for i in keep] for r in rows])]
        by_capture = {f.capture: f for f in flags}
        for o in cal["cameras"][cam].get("outliers") or []:
            f = by_capture.get(o["capture"])
            if f is not None:  # the diagnosis says which detection is wrong (calib_core.diagnose)
                out.append(f"- ⚠ {escape_md(f.text)}")
                continue
            for why in o.get("reasons", []):
                out.append("- ⚠ " + escape_md(f"{cam} {o['capture']}: {why}"))
    ti = table_i_rows(cal)
    if ti:
        out += ["", "**Table I** (independent solves, mm)", "", md_table(*ti)]
    for w in cal.get("warnings") or []:
        out.append(f"- ⚠ {escape_md(w)}")
    return "\n".join(out)


class SolvePanel:
    def __init__(self, wb):
        self.wb = wb
        gui = wb.server.gui
        self.button = wb.solve_button
        with wb.tab_solve:
            self.scale = gui.add_checkbox("Force range-scale estimate", False,
                                          hint="Off: the sound-speed (range) scale is estimated where observable when a test finds "
                                               "a scale error, as 'sonarcal calibrate' does; on: always (like --scale)")
            self.robust = gui.add_dropdown("Robust loss", ("none", "huber", "cauchy"), initial_value="none")
            self.status = gui.add_markdown("")
            self.summary = gui.add_markdown(describe(None))
            self.plot = gui.add_image(np.full((40, 200, 3), 255, np.uint8), label="Residuals per capture", visible=False)
        self.button.on_click(guarded(wb.server, "Solve failed")(self._solve))
        wb.refresher.on("calibration", self.refresh)
        wb.refresher.on("flags", self.refresh)

    def _solve(self, event) -> None:
        from calib_core.pipeline import detect_session, pending
        from calib_core.solve.calibrate import calibrate_session

        st = self.wb.state

        def job(progress):
            session, dets, _cal = st.snapshot()
            if pending(session, dets, redetect_auto=False):  # detect only what has no entry yet
                with st.lock:
                    data = st.data
                st.merge_automatic(detect_session(data, dets, progress=progress, redetect_auto=False), session=session)
                session, dets, _cal = st.snapshot()
            # the detections on screen, as reviewed: automatic ones are not detected again
            result = calibrate_session(session, dets, self.options(), progress=progress)
            st.set_calibration(result, session=session)
            notify(self.wb.server, None, "Solved", "results/calibration.json saved", color="green", seconds=4)

        self.wb.jobs.start("solve", job)
        self.button.disabled = True
        self.status.content = "Solving… (the workbench stays usable)"

    def options(self) -> dict:
        """The options dict 'sonarcal calibrate' builds from its flags (same defaults: automatic entries
        whose fingerprint still matches are reused as shown; the job first detects missing entries)."""
        return {"estimate_scale": True if self.scale.value else None, "robust": None if self.robust.value == "none" else self.robust.value,
                "detect": True, "leave_one_out": True}

    def job_finished(self, name: str) -> None:
        if name == "solve":
            self.button.disabled = False
            self.status.content = ""

    def refresh(self) -> None:
        cal = self.wb.state.calibration
        self.summary.content = describe(cal, list(self.wb.state.flags))
        img = residual_plot(cal) if cal else None
        if img is not None:
            self.plot.image = img
        self.plot.visible = img is not None
