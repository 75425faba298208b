"""Flags panel: what looks wrong before (and after) any Solve, each flag a link to its fix.

A background thread re-runs calib_core.diagnose whenever the detections change (coalescing
bursts) and publishes "flags". Each flag is a button: one click selects the capture, puts
the implicated sensor on screen with the predicted position marked (the camera's image
board for an image or moved flag, the sonar centre with its drag handle for a sonar flag),
sets "Apply to" so that Reject acts on the right thing, and says what the fix is.
"""

from __future__ import annotations

import threading

from app.common import guarded, notify
from calib_core.diagnose import MIN_CAPTURES, diagnose_session
from calib_core.markup import escape_md

MAX_BUTTONS = 8


class Diagnoser:
    """Runs the diagnosis in its own thread after each change of the detections."""

    def __init__(self, state):
        self.state = state
        self._cv = threading.Condition()
        self._dirty = False
        self._busy = False
        self._stop = False
        threading.Thread(target=self._run, name="workbench-diagnose", daemon=True).start()
        state.bus.subscribe("detections", self.mark)
        state.bus.subscribe("session", self.mark)

    def mark(self) -> None:
        with self._cv:
            self._dirty = True
            self._cv.notify_all()

    def stop(self) -> None:
        with self._cv:
            self._stop = True
            self._cv.notify_all()

    def wait_idle(self, timeout: float = 30.0) -> bool:
        with self._cv:
            return self._cv.wait_for(lambda: not self._dirty and not self._busy, timeout)

    def _run(self) -> None:
        while True:
            with self._cv:
                self._cv.wait_for(lambda: self._dirty or self._stop)
                if self._stop:
                    return
                self._dirty, self._busy = False, True
            try:
                self._diagnose()
            except Exception as e:  # a diagnosis that fails must not stop the workbench
                self.state.flags = []
                self.state.flags_note = f"diagnosis failed: {type(e).__name__}: {e}"
                self.state.bus.publish("flags")
            finally:
                with self._cv:
                    self._busy = False
                    self._cv.notify_all()

    def _diagnose(self) -> None:
        st = self.state
        if st.session is None:
            return
        session, dets, _cal = st.snapshot()
        with st.lock:
            data = st.data
        notes: list[str] = []
        flags = diagnose_session(data, dets, notes)
        with st.lock:
            if st.session is not session:
                return  # another session was opened meanwhile
            st.flags = flags
            st.flags_note = " ".join(notes) if notes else ("" if any(st.session.cameras) else "no camera")
        st.bus.publish("flags")


class FlagsPanel:
    def __init__(self, wb):
        self.wb = wb
        gui = wb.server.gui
        with wb.tab_review:
            self.folder = gui.add_folder("Flags (click one to go there)", order=-10)
        with self.folder:
            self.header = gui.add_markdown("Flags appear once " f"{MIN_CAPTURES} captures have both detections.")
            self.buttons = [gui.add_button(f"flag {k}", visible=False, color="orange") for k in range(MAX_BUTTONS)]
        for k, b in enumerate(self.buttons):
            b.on_click(guarded(wb.server, "Could not go to the flag")(lambda e, k=k: self.go(e, k)))
        self.shown: list = []
        wb.refresher.on("flags", self.refresh)

    def refresh(self) -> None:
        st = self.wb.state
        flags = list(st.flags)
        self.shown = flags[:MAX_BUTTONS]
        if getattr(st, "flags_note", ""):
            self.header.content = escape_md(st.flags_note)
        elif not flags:
            self.header.content = ("No flags: every capture with both detections fits the others."
                                   if st.session is not None else "")
        else:
            self.header.content = (f"**{len(flags)} flagged** by the solver's consistency check, re-run after every "
                                   "detection and change (no Solve needed). Hover a flag for its fix; click it to go there.")
        for k, b in enumerate(self.buttons):
            if k < len(self.shown):
                f = self.shown[k]
                b.label = f"⚠ {f.title}"
                b.hint = f.text
                b.visible = True
            else:
                b.visible = False

    def go(self, event, k: int) -> None:
        """Take the clicking client to flag ``k``: select, show the sensor, set the fix up."""
        f = self.shown[k]
        st = self.wb.state
        st.select(f.capture)
        st.bus.publish("focus", client=event.client, cid=f.capture, sensor=f.sensor, flag=f)
        notify(self.wb.server, event.client, f.title, f.text, color="orange", seconds=20)
