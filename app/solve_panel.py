"""Solve panel: run calib_core's solver in a worker thread, then show what it returned.

The workbench saves exactly the dict ``calibrate_session`` returns (via
calib_core.results.save_calibration), so the browser and ``sonarcal calibrate`` agree.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import viser

from app.common import guarded, notify
from calib_core.geometry import rotvec_from_T

BAR_RGB = [(255, 120, 0), (0, 150, 150), (150, 60, 220), (120, 120, 0)]


def _f(x, fmt="{:.3f}", none="-"):
    return none if x is None or (isinstance(x, float) and not math.isfinite(x)) else fmt.format(x)


def residual_rows(cal: dict) -> dict[str, list[dict]]:
    """{camera: [per-capture rows with capture, residual_norm_px, used, flags]} from a calibration."""
    out = {}
    for cam, c in (cal or {}).get("cameras", {}).items():
        rows = c.get("residuals") or []
        if isinstance(rows, dict):
            rows = [dict(v, capture=k) for k, v in rows.items()]
        out[cam] = [r for r in rows if isinstance(r, dict) and "capture" in r]
    return out


def residual_plot(cal: dict, width: int = 900, height: int = 360) -> np.ndarray | None:
    """Bar chart (RGB image) of each capture's reprojection residual (px), per camera;
    captures the solver left out or flagged are drawn hatched red."""
    rows = residual_rows(cal)
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
    left, bottom, top = 60, 60, 30
    ph = height - bottom - top
    gw = (width - left - 10) / len(caps)
    bw = gw * 0.8 / max(len(rows), 1)
    font = cv2.FONT_HERSHEY_SIMPLEX
    for k in range(5):
        y = int(top + ph - ph * k / 4)
        cv2.line(img, (left, y), (width - 10, y), (225, 225, 225), 1)
        cv2.putText(img, f"{vmax * k / 4:.1f}", (5, y + 4), font, 0.4, (60, 60, 60), 1, cv2.LINE_AA)
    cv2.putText(img, "reprojection residual (px) per capture", (left, 18), font, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
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
        cv2.putText(img, str(cid)[:8], (int(x0), height - bottom + 18 + 14 * (i % 2)), font, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    for j, cam in enumerate(rows):
        cv2.rectangle(img, (width - 150, 8 + 16 * j), (width - 140, 18 + 16 * j), BAR_RGB[j % len(BAR_RGB)], -1)
        cv2.putText(img, cam, (width - 135, 18 + 16 * j), font, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    return img


def describe(cal: dict) -> str:
    """Markdown summary: pose and uncertainty per camera, range scale, outliers, Table I."""
    if not cal:
        return "No calibration yet: press **Solve**."
    out = []
    for cam, c in cal.get("cameras", {}).items():
        T = np.asarray(c["T_cam_sonar"], float)
        rv = np.degrees(rotvec_from_T(T))
        t = T[:3, 3]
        cov = c.get("covariance")
        sd = np.sqrt(np.clip(np.diag(np.asarray(cov, float)), 0, None)) if cov is not None else None
        out.append(f"**{cam}**: rms {_f(c.get('rms_reprojection_px'), '{:.2f}')} px over "
                   f"{len(c.get('captures_used') or [])} captures")
        out.append(f"- translation (m): {t[0]:+.4f} {t[1]:+.4f} {t[2]:+.4f}"
                   + (f" ± {1000 * sd[3]:.1f} / {1000 * sd[4]:.1f} / {1000 * sd[5]:.1f} mm" if sd is not None else ""))
        out.append(f"- rotation vector (deg): {rv[0]:+.3f} {rv[1]:+.3f} {rv[2]:+.3f}"
                   + (" ± " + " / ".join(f"{math.degrees(v):.3f}" for v in sd[:3]) if sd is not None else ""))
        out.append(f"- sonar origin from {cam}: {np.linalg.norm(t):.4f} m")
        for r in residual_rows(cal).get(cam, []):
            for fl in r.get("flags") or []:
                out.append(f"- ⚠ {r['capture']}: {fl.get('reason', fl) if isinstance(fl, dict) else fl}")
    scale = cal.get("range_scale")
    if isinstance(scale, dict):
        out.append(f"\n**Sound-speed (range) scale**: {_f(scale.get('value'), '{:.4f}')} ± {_f(scale.get('sigma'), '{:.4f}')}"
                   + (f" ({scale['note']})" if scale.get("note") else ""))
    elif scale is not None:
        out.append(f"\n**Sound-speed (range) scale**: {_f(float(scale), '{:.4f}')}")
    tab = cal.get("table_i")
    if isinstance(tab, dict) and tab.get("pairs"):
        out.append("\n**Table I** (baselines, m)\n\n| pair | estimated | measured | error % |\n|---|---|---|---|")
        for pair, r in tab["pairs"].items():
            out.append(f"| {pair} | {_f(r.get('estimated_m'), '{:.4f}')} | {_f(r.get('measured_m'), '{:.4f}')} | "
                       f"{_f(r.get('error_pct'), '{:+.2f}')} |")
    for w in cal.get("warnings") or []:
        out.append(f"- ⚠ {w}")
    return "\n".join(out)


class SolvePanel:
    def __init__(self, wb):
        self.wb = wb
        gui = wb.server.gui
        with wb.tab_solve:
            self.button = gui.add_button("Solve", icon=viser.Icon.PLAYER_PLAY, color="blue",
                                         hint="Detect what is not validated, solve every camera, save results/calibration.json")
            self.status = gui.add_markdown("")
            self.summary = gui.add_markdown(describe(None))
            self.plot = gui.add_image(np.full((40, 200, 3), 255, np.uint8), label="Residuals per capture", visible=False)
        self.button.on_click(guarded(wb.server, "Solve failed")(self._solve))
        wb.refresher.on("calibration", self.refresh)

    def _solve(self, event) -> None:
        from calib_core.solve.calibrate import calibrate_session

        st = self.wb.state

        def job(progress):
            session, dets, _cal = st.snapshot()
            result = calibrate_session(session, dets, progress=progress)
            st.set_calibration(result)
            notify(self.wb.server, None, "Solved", "results/calibration.json saved", color="green", seconds=4)

        self.wb.jobs.start("solve", job)
        self.button.disabled = True
        self.status.content = "Solving… (the workbench stays usable)"

    def job_finished(self, name: str) -> None:
        if name == "solve":
            self.button.disabled = False
            self.status.content = ""

    def refresh(self) -> None:
        cal = self.wb.state.calibration
        self.summary.content = describe(cal)
        img = residual_plot(cal) if cal else None
        if img is not None:
            self.plot.image = img
        self.plot.visible = img is not None
