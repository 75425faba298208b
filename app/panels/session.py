"""Session panel: open another session by path or by uploading a zipped session; downloads."""

from __future__ import annotations

import json


from app.common import error_text, guarded, notify
from app.upload_stream import UploadReceiver
from app.uploads import MAX_UPLOAD_BYTES, safe_unpack_zip, upload_limit_text
from calib_core.detections import detections_path
from calib_core.errors import SessionError
from calib_core.markup import escape_md
from calib_core.results import calibration_path


def calibration_line(cal: dict | None) -> str:
    """The Session tab's calibration line: what is in use now."""
    if not cal:
        return "none yet (press Solve)"
    cams = cal.get("cameras") or {}
    rms = ", ".join(f"{c} RMS {v['rms_reprojection_px']:.2f} px" for c, v in cams.items()
                    if isinstance(v.get("rms_reprojection_px"), (int, float)))
    when = cal.get("created") or cal.get("timestamp") or ""
    return f"results/calibration.json ({rms or ', '.join(cams)}){' ' + str(when) if when else ''}"


class SessionPanel:
    def __init__(self, wb):
        self.wb = wb
        gui = wb.server.gui
        g = guarded(wb.server, "Could not open the session")
        with wb.tab_session:
            self.info = gui.add_markdown("No session open.")
            self.path = gui.add_text("Session folder", "", hint="A folder holding session.yaml (on the server's disk)")
            self.open_btn = gui.add_button("Open folder")
            self.upload = gui.add_upload_button(f"Upload zipped session ({upload_limit_text()})",
                                                mime_type="application/zip")
            self.dl_cal = gui.add_button("Download calibration.json")
            self.dl_det = gui.add_button("Download detections.yaml")
        self.open_btn.on_click(g(self._open_path))
        self.receiver = UploadReceiver(wb.server, self.upload, wb.uploads, MAX_UPLOAD_BYTES,
                                       on_file=self._on_upload, on_refuse=self._on_refuse)
        self.dl_cal.on_click(guarded(wb.server, "Download failed")(lambda e: self._download(e, "calibration")))
        self.dl_det.on_click(guarded(wb.server, "Download failed")(lambda e: self._download(e, "detections")))
        wb.refresher.on("calibration", self.refresh)

    def _open_path(self, event) -> None:
        text = self.path.value.strip()
        if not text:
            raise ValueError("type the path of a session folder first")
        self.wb.open_session(text, check_root=True)
        notify(self.wb.server, None, "Session opened", self.wb.state.session.name, color="green", seconds=4)

    def _on_upload(self, client_id, name: str, path) -> None:
        """A complete upload streamed to ``path`` (deleted here): unpack it and open it."""
        client = self.wb.server.get_clients().get(client_id)
        try:
            try:
                root = safe_unpack_zip(path, self.wb.uploads_dir, label=name or "upload.zip")
            finally:  # the archive is not needed once unpacked (or refused)
                path.unlink(missing_ok=True)
            try:
                self.wb.open_session(root)
            except BaseException:
                self.wb.uploads.keep_only(self.wb.state.session.root if self.wb.state.session else None)
                raise
        except Exception as e:  # a bad archive or session: one notice, the server carries on
            notify(self.wb.server, client, "Could not open the session", error_text(e))
            return
        notify(self.wb.server, None, "Session uploaded", f"{name}: {self.wb.state.session.name}", color="green", seconds=4)

    def _on_refuse(self, client_id, name: str, problem: str) -> None:
        notify(self.wb.server, self.wb.server.get_clients().get(client_id), "Upload refused", f"{name}: {problem}")

    def _download(self, event, what: str) -> None:
        s = self.wb.state.require()
        path = calibration_path(s) if what == "calibration" else detections_path(s)
        if not path.is_file():
            raise SessionError(path, "not written yet" + (" (run Solve first)" if what == "calibration" else ""))
        event.client.send_file_download(path.name, path.read_bytes())

    def refresh(self) -> None:
        s = self.wb.state.session
        if s is None:
            return
        cal = self.wb.state.calibration
        lines = [f"**{escape_md(s.name)}**", f"- folder: {escape_md(s.root)}",
                 f"- sphere diameter: {s.sphere_diameter_m * 1000:.1f} mm",
                 f"- sonar: {escape_md(s.sonar_model or '-')}; sound speed {s.sound_speed_m_s or '-'} m/s",
                 f"- cameras: {escape_md(', '.join(s.cameras))}; captures: {len(s.captures)}",
                 f"- ground truth: {'yes (magenta in 3D)' if self.wb.state.ground_truth else 'no'}",
                 f"- calibration: {calibration_line(cal)}"]
        if s.measured_m:
            lines.append("- measured: " + escape_md(json.dumps(s.measured_m, ensure_ascii=False)))
        self.info.content = "\n".join(lines)
        if not self.path.value:
            self.path.value = str(s.root)
