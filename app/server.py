"""The workbench server: one viser server, one shared :class:`WorkbenchState`, the panels.

``server.scene`` and ``server.gui`` are shared by every browser, so all clients see the
same session, selection and results; per-client things (the viewpoint, the pick mode,
notifications) go through ``client``. Every callback is guarded: a bad action or file
shows a notification in the page and the server carries on.
"""

from __future__ import annotations

import logging
import threading
import time
from pathlib import Path

import viser

from app.common import JobRunner, Refresher, error_text, notify
from app.guard import ConnectionGuard, new_token, start_guarded
from app.uploads import UploadStore, port_taken_warning, release_session_lock
from app.state import WorkbenchState
from calib_core.errors import SessionError
from calib_core.markup import escape_md

log = logging.getLogger("sonarcal.app")
FIRST_CLIENT_WAIT_S = 2.0  # how long detection waits for a first page before starting anyway
DETECT_GRACE_S = 1.0  # after the first page connects: let it receive the session first
HEAVY_GRACE_S = 0.3  # after the first page connects: images and clouds follow its panel


class Workbench:
    """A running workbench.

    Args:
        session_path: session folder to open at start (optional).
        host: interface to bind; 127.0.0.1 (this machine only) unless told otherwise.
        port: TCP port; 0 picks a free one (see :attr:`port`).
        allowed_roots: folders the browser's path field may open (default: the session's
            parent folder and the current folder); uploads always go to ``uploads_dir``.
    """

    def __init__(self, session_path=None, host: str = "127.0.0.1", port: int = 8080,
                 allowed_roots=None, uploads_dir=None, verbose: bool = False, token: str | None = "auto"):
        self.uploads = UploadStore(uploads_dir)
        self.uploads_dir = self.uploads.root
        if allowed_roots is None:
            allowed_roots = [Path.cwd()] + ([Path(session_path).resolve().parent] if session_path else [])
        self.state = WorkbenchState(allowed_roots=list(allowed_roots) + [self.uploads_dir])
        self.bus = self.state.bus
        self._stopped = False
        self._start_server(host, port, verbose, token)
        self.refresher = Refresher(on_error=lambda kind, e: notify(self.server, None, f"Display of {kind} failed", error_text(e)))
        self.refresher.hold()  # images and clouds wait until the first page has its panel (or a moment)
        self.jobs = JobRunner(on_progress=self._progress, on_error=self._job_error)
        self._first_client = threading.Event()  # detection waits for the first page to load (or a moment)
        self._detect_due = threading.Event()
        self._detect_due.set()
        self._framed: set = set()  # clients whose view was framed on the open session
        self._build_frame()
        self._build_panels()
        self.refresher.on("session", self._on_session)
        self.refresher.on("after-session", self._after_session)
        self.refresher.on("home", self._frame_new_clients, heavy=True)  # framing may load a cloud
        self.state.subscribe(self.refresher.mark)  # every named state event asks for a refresh of that name
        self.server.on_client_connect(self._on_connect)
        threading.Thread(target=self._release_after_first_page, name="workbench-first-page", daemon=True).start()
        if session_path is not None:
            try:
                self.open_session(session_path)
            except BaseException:
                self.stop()
                raise

    def _start_server(self, host: str, port: int, verbose: bool, token: str | None) -> None:
        """The viser server behind the Origin/token guard, its theme and panel placement."""
        self.guard = ConnectionGuard(new_token() if token == "auto" else token, host)
        self.requested_port = port
        self.server = start_guarded(self.guard, lambda: viser.ViserServer(
            host=host, port=port, label="sonarcal workbench", verbose=verbose))
        self.guard.port = self.server.get_port()
        self.port_warning = port_taken_warning(port, self.guard.port)
        if self.port_warning:
            log.warning(self.port_warning)
        self.server.gui.configure_theme(control_width="large", dark_mode=False, show_share_button=False)
        self.server.gui.main_panel.dock_right()  # beside the 3D view, so the view is never covered

    def _build_frame(self) -> None:
        """Title, progress, the Solve button (above the tabs: the review loop never switches tab
        to solve) and the tabs."""
        gui = self.server.gui
        self.title = gui.add_markdown("**sonarcal workbench**: no session open")
        self.progress_label = gui.add_markdown("", visible=False)
        self.progress = gui.add_progress_bar(0.0, visible=False, animated=True)
        self.solve_button = gui.add_button(
            "Solve", color="blue", hint="Detect what is not validated, solve every camera, save results/calibration.json")
        tabs = gui.add_tab_group()
        self.tab_review = tabs.add_tab("Review")
        self.tab_solve = tabs.add_tab("Solve")
        self.tab_view = tabs.add_tab("View")
        self.tab_fused = tabs.add_tab("Fused")
        self.tab_session = tabs.add_tab("Session")
        self.tab_plan = tabs.add_tab("Plan")

    def _build_panels(self) -> None:
        from app.panels.flags import Diagnoser, FlagsPanel
        from app.panels.fused import FusedPanel
        from app.panels.images import ImagePanels
        from app.panels.motion import MotionPanel
        from app.panels.plan import PlanPanel
        from app.panels.review import ReviewPanel
        from app.panels.scene3d import Scene3D
        from app.panels.session import SessionPanel
        from app.panels.solve import SolvePanel

        self.scene3d = Scene3D(self)
        self.images = ImagePanels(self)
        self.flags = FlagsPanel(self)
        self.review = ReviewPanel(self)
        self.solve = SolvePanel(self)
        self.fused = FusedPanel(self)
        self.session_panel = SessionPanel(self)
        self.plan = PlanPanel(self, self.tab_plan)
        self.motion_panel = MotionPanel(self)  # the target-motion track of an imported session
        self.diagnoser = Diagnoser(self.state)

    # ---- lifecycle -------------------------------------------------------
    @property
    def host(self) -> str:
        return self.server.get_host()

    @property
    def port(self) -> int:
        return self.server.get_port()

    @property
    def token(self) -> str | None:
        return self.guard.token

    @property
    def url(self) -> str:
        """The full URL to open, token included (``--no-token``: without one)."""
        base = f"http://{self.host}:{self.port}/"
        return base if self.token is None else f"{base}?token={self.token}"

    def stop(self) -> None:
        """Stop the server; remove the uploads and this server's lock file. Safe to call twice."""
        if self._stopped:
            return
        self._stopped = True
        try:
            self.jobs.cancel(10)  # a running detection stops at its next step; nothing half-written
            self.refresher.wait_idle(10, owed=False)  # what is held for a first page is dropped
            self.refresher.stop()
            diagnoser = getattr(self, "diagnoser", None)
            if diagnoser is not None:
                diagnoser.stop()
            self.server.stop()
        finally:
            self.uploads.cleanup()
            release_session_lock(self.state.session.root if self.state.session is not None else None)

    def wait_idle(self, timeout: float = 60.0) -> bool:
        """Block until running jobs and pending display refreshes are done (tests, benchmarks)."""
        self.refresher.wait_idle(timeout)  # a session refresh may start the detection job
        self._detect_due.wait(timeout)
        self.jobs.join(timeout)
        self.diagnoser.wait_idle(timeout)
        return self.refresher.wait_idle(timeout)

    # ---- session -----------------------------------------------------------
    def open_session(self, path, check_root: bool = False) -> None:
        """Open a session folder; detect what detections.yaml lacks in the background."""
        if self.jobs.running is not None:
            raise SessionError(Path(str(path)), f"'{self.jobs.running}' is still running on the open session; "
                               "open another one when it has finished")
        old = self.state.session.root if self.state.session is not None else None
        self.state.open(path, check_root=check_root)  # detection of what is missing starts once it is on screen
        if old is not None and old != self.state.session.root:
            release_session_lock(old)  # the lock file of the session left behind
        self.uploads.keep_only(self.state.session.root)  # a replaced uploaded session is deleted

    def start_detection(self, captures=None, redetect_auto: bool = False) -> None:
        from calib_core.pipeline import detect_session

        st = self.state

        def job(progress):
            session, dets, _cal = st.snapshot()
            with st.lock:
                data = st.data
            merged = detect_session(data, dets, progress=progress, captures=captures, redetect_auto=redetect_auto)
            st.merge_automatic(merged, session=session)

        self.jobs.start("detection", job)

    def _on_session(self) -> None:
        s = self.state.session
        if s is not None:
            self.title.content = (f"**sonarcal workbench**: {escape_md(s.name)} ({len(s.captures)} captures, "
                                  f"cameras {escape_md(', '.join(s.cameras))})")
        for w in self.state.warnings:
            notify(self.server, None, "Session warning", w, color="yellow")
        self.images.rebuild()
        self.scene3d.rebuild()
        self.review.rebuild()
        self.solve.refresh()
        self.fused.rebuild()
        self.session_panel.refresh()
        self._framed.clear()  # every page is framed on the new session (once its cloud may load)
        self.refresher.mark("detections", "calibration", "selection", "after-session", "home")

    def _after_session(self) -> None:
        """Once the new session is on screen, detect what detections.yaml lacks (in the background),
        after the first page has received the session: detection competes for the same CPU."""
        pending = self.state.missing() if self.state.session is not None else []
        if not pending or self.jobs.running is not None:
            return
        self._detect_due.clear()
        threading.Thread(target=self._deferred_detection, args=(pending, self.state.session),
                         name="workbench-detect-later", daemon=True).start()

    def _deferred_detection(self, pending, session) -> None:
        try:
            if self._first_client.wait(FIRST_CLIENT_WAIT_S):
                time.sleep(DETECT_GRACE_S)
            if self.state.session is session and self.jobs.running is None and not self._stopped:
                self.start_detection(pending, redetect_auto=False)
        except Exception as e:  # reported in the page
            self._job_error("detection", e)
        finally:
            self._detect_due.set()

    def _on_connect(self, client: viser.ClientHandle) -> None:
        self._first_client.set()
        self.refresher.mark("home")

    def _frame_new_clients(self) -> None:
        """Frame the open session in every page not framed on it yet (a new page, a new session)."""
        for cid, client in self.server.get_clients().items():
            if cid not in self._framed:
                self._framed.add(cid)
                self.scene3d.home_view(client)

    def _release_after_first_page(self) -> None:
        """Let images and clouds go once the first page has received its panel (it connects
        after its 3D view is up), or after FIRST_CLIENT_WAIT_S without a page: the page is
        usable sooner when they do not compete with it for the CPU."""
        if self._first_client.wait(FIRST_CLIENT_WAIT_S):
            time.sleep(HEAVY_GRACE_S)
        self.refresher.release()

    # ---- jobs --------------------------------------------------------------
    def _progress(self, name: str, pct: float, label: str) -> None:
        if pct < 0:
            self.progress.visible = False
            self.progress_label.visible = False
            self.solve.job_finished(name)
            return
        self.progress.value = float(min(max(pct, 0.0), 100.0))
        self.progress_label.content = escape_md(f"{name}: {label}")
        self.progress.visible = True
        self.progress_label.visible = True

    def _job_error(self, name: str, e: BaseException) -> None:
        notify(self.server, None, f"{name.capitalize()} failed", error_text(e), seconds=15.0)


def serve(session_path, host: str = "127.0.0.1", port: int = 8080, token: str | None = "auto") -> Workbench:
    """Start a workbench (returns at once; the server runs in its own threads)."""
    return Workbench(session_path, host=host, port=port, token=token)
