"""The workbench's shared state: one session, its detections, undo and change records.

Pure Python (no viser): every browser client works on the one :class:`WorkbenchState`
of the server. Each change is made under one lock, saved at once to
``detections.yaml`` (atomically, via calib_core) and recorded in each touched entry's
``history`` list (time, action, status, center, client, change number, previous content).
Undo and redo are replayed from those records (calib_core.history), so they survive reloads
and restarts and are shared by every client.
All geometry and computation are calib_core's; this module only holds and routes data.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import os
import threading
import zlib
from collections import OrderedDict
from pathlib import Path
from typing import Callable

from calib_core.detections import (
    detections_path,
    load_detections,
    merge_auto,
    now_iso,
    save_detections,
)
from calib_core import history
from calib_core.errors import SessionError
from calib_core.results import calibration_path, load_calibration, save_calibration
from calib_core.session import Session, load_session

SENSOR_SONAR = "sonar"
RESTORED_MISSING = "restored_missing"  # an undo back to "no entry": detect afresh


EVENTS = {
    "session": "a session was opened (panels rebuild)",
    "detections": "detections.yaml changed (any entry, any client or process)",
    "calibration": "the calibration in use changed (a Solve, or opening a session)",
    "selection": "another capture was selected",
    "flags": "the diagnosis of suspicious entries changed (calib_core.diagnose)",
    "corrected": "an operator corrected one entry (cid=, sensor=)",
    "fused": "the fused cloud shown changed (cid= or None)",
    "focus": "a client asked to look at one sensor of one capture (client=, cid=, sensor=)",
}


class EventBus:
    """Named state events (:data:`EVENTS`): panels subscribe to what they show and publish what
    they change, instead of calling each other. ``subscribe("*", fn)`` gets ``fn(name)`` for
    every event; a named subscription gets ``fn(**payload)``."""

    def __init__(self):
        self._subs: dict[str, list[Callable]] = {}
        self._lock = threading.Lock()

    def subscribe(self, name: str, fn: Callable) -> None:
        if name != "*" and name not in EVENTS:
            raise KeyError(f"unknown event {name!r} (known: {', '.join(EVENTS)})")
        with self._lock:
            self._subs.setdefault(name, []).append(fn)

    def publish(self, name: str, **payload) -> None:
        if name not in EVENTS:
            raise KeyError(f"unknown event {name!r}")
        with self._lock:
            named, every = list(self._subs.get(name, [])), list(self._subs.get("*", []))
        for fn in named:
            fn(**payload)
        for fn in every:
            fn(name)


@dataclasses.dataclass
class ClientModes:
    """Per-browser interaction modes shared by the panels (keyed by viser client id)."""

    picking: set = dataclasses.field(default_factory=set)  # next 3D click picks the sonar centre
    viewing: dict = dataclasses.field(default_factory=dict)  # client -> (camera, eye) after "View through"


@dataclasses.dataclass
class Change:
    """One operator action (possibly several entries), as undo/redo report it."""

    id: int
    client: str
    action: str
    items: list  # [(capture_id, sensor, previous entry or None, new entry)]


class WorkbenchState:
    """Session + detections + calibration shared by every client of one server.

    Args:
        allowed_roots: folders a session may be opened from by path (the browser's
            path field); ``None`` allows any folder.
        cloud_cache: how many point clouds to keep in memory.
    """

    def __init__(self, allowed_roots: list[Path] | None = None, cloud_cache: int = 6):
        self.lock = threading.RLock()
        self.allowed_roots = None if allowed_roots is None else [Path(p).resolve() for p in allowed_roots]
        self.session: Session | None = None
        self.detections: dict = {}
        self.calibration: dict | None = None
        self.ground_truth: dict | None = None
        self.selected: str | None = None
        self.data = None  # calib_core.pipeline.SessionData: intrinsics/background caches
        self.version = 0
        self.cal_version = 0  # bumps whenever the calibration in use changes
        self.warnings: list[str] = []
        self.bus = EventBus()
        self.modes = ClientModes()
        self.flags: list = []  # calib_core.diagnose.Flag, newest diagnosis
        self.flags_note = ""
        self._centres: OrderedDict = OrderedDict()
        self._det_sig = None
        self._images: OrderedDict = OrderedDict()
        self._clouds: OrderedDict = OrderedDict()
        self._cloud_cache = cloud_cache

    # ---- events ------------------------------------------------------------
    def subscribe(self, fn: Callable[[str], None]) -> None:
        """``fn(kind)`` runs after every event (see :data:`EVENTS`)."""
        self.bus.subscribe("*", fn)

    def _emit(self, kind: str) -> None:
        self.bus.publish(kind)

    # ---- session -----------------------------------------------------------
    def check_allowed(self, path: Path) -> Path:
        p = Path(path).expanduser()
        rp = p.resolve()
        if self.allowed_roots is not None and not any(rp == r or r in rp.parents for r in self.allowed_roots):
            roots = ", ".join(str(r) for r in self.allowed_roots)
            raise SessionError(p, f"outside the folders this server may open ({roots})")
        return p

    def open(self, path: str | Path, check_root: bool = False) -> None:
        """Load a session folder (manifest, detections, calibration, ground truth)."""
        path = self.check_allowed(Path(path)) if check_root else Path(path)
        session = load_session(path)
        dets = load_detections(session)
        warnings = []
        cal = None
        if calibration_path(session).exists():
            try:
                cal = load_calibration(calibration_path(session))
            except SessionError as e:
                warnings.append(str(e))
        gt = None
        try:
            from calib_core.synth.ground_truth import load_ground_truth

            gt = load_ground_truth(session.root)
        except ImportError:
            gt = None
        except SessionError as e:
            warnings.append(str(e))
        from calib_core.pipeline import SessionData

        with self.lock:
            self.session, self.detections, self.calibration, self.ground_truth = session, dets, cal, gt
            self.data = SessionData(session)
            self.data.adopt_beam_width(dets)
            self.cal_version += 1
            self.selected = session.captures[0].id
            self.flags, self.flags_note = [], ""  # the diagnosis of the new session follows
            self._centres.clear()
            self.warnings = warnings
            self._images.clear()
            self._clouds.clear()
            self._det_sig = self._disk_sig()
            self.version += 1
        self._emit("session")

    def require(self) -> Session:
        if self.session is None:
            raise SessionError(Path("."), "no session is open (open one by path or upload a zip)")
        return self.session

    # ---- cached data (calib_core loaders) ----------------------------------
    def camera(self, cam: str):
        self.require()
        with self.lock:
            return self.data.camera(cam)

    def cloud(self, cid: str):
        from calib_core.io.clouds import load_cloud

        with self.lock:
            if cid in self._clouds:
                self._clouds.move_to_end(cid)
                return self._clouds[cid]
            path = self.require().capture(cid).cloud_path
        c = load_cloud(path)
        with self.lock:
            self._clouds[cid] = c
            while len(self._clouds) > self._cloud_cache:
                self._clouds.popitem(last=False)
        return c

    def image(self, cid: str, cam: str):
        """RGB uint8 image of camera ``cam`` for capture ``cid`` (None if the capture has none)."""
        from calib_core.io.images import load_image

        with self.lock:
            key = (cid, cam)
            if key in self._images:
                return self._images[key]
            path = self.require().capture(cid).image_paths.get(cam)
        img = None if path is None else load_image(path)
        with self.lock:
            self._images[key] = img
            while len(self._images) > 12:
                self._images.popitem(last=False)
        return img

    # ---- selection -----------------------------------------------------------
    def select(self, cid: str) -> None:
        s = self.require()
        s.capture(cid)  # raises for an unknown id
        with self.lock:
            changed = cid != self.selected
            self.selected = cid
        if changed:
            self._emit("selection")

    def step(self, delta: int, order: list[str] | None = None) -> str:
        """Select the next/previous capture in ``order`` (manifest order by default)."""
        s = self.require()
        ids = order or [c.id for c in s.captures]
        with self.lock:
            i = ids.index(self.selected) if self.selected in ids else -1
            cid = ids[(i + delta) % len(ids)]
        self.select(cid)
        return cid

    # ---- detections ----------------------------------------------------------
    def entry(self, cid: str, sensor: str) -> dict | None:
        with self.lock:
            e = self.detections.get(cid, {}).get(sensor)
            return copy.deepcopy(e)

    def sensors(self, cid: str) -> list[str]:
        """Sensors that apply to capture ``cid``: sonar and the cameras it has images for."""
        cap = self.require().capture(cid)
        return [SENSOR_SONAR] + [c for c in self.session.cameras if c in cap.image_paths]

    def _disk_sig(self):
        try:  # the content's checksum too: an edit within the file system's mtime granularity counts
            path = detections_path(self.session)
            st = path.stat()
            return (st.st_mtime_ns, st.st_size, st.st_ino, zlib.crc32(path.read_bytes()))
        except (FileNotFoundError, AttributeError):
            return None

    @contextlib.contextmanager
    def _file_lock(self):
        """Hold this process's lock and an advisory lock on the session folder, so that two
        servers (or a server and a tool) editing one session serialise their read-modify-writes."""
        with self.lock:
            fd = None
            try:
                import fcntl

                fd = os.open(self.session.root / ".detections.yaml.lock",
                             os.O_CREAT | os.O_RDWR | getattr(os, "O_NOFOLLOW", 0), 0o644)  # never a symlink out
                fcntl.flock(fd, fcntl.LOCK_EX)
            except (ImportError, OSError):  # no flock (or read-only folder): the process lock still holds
                if fd is not None:
                    os.close(fd)
                fd = None
            try:
                yield
            finally:
                if fd is not None:
                    os.close(fd)  # closing releases the flock

    def _sync_from_disk(self) -> None:
        """Reload detections.yaml if someone else (the CLI, an editor) changed it."""
        sig = self._disk_sig()
        if sig != self._det_sig:
            self.detections = load_detections(self.session)
            self._det_sig = sig

    def apply(self, updates: list[tuple[str, str, dict | None]], client: str, action: str) -> Change:
        """Set several entries in one action; save at once; record it in each entry's history.

        ``updates`` holds (capture_id, sensor, new entry or None to clear). Each new entry's
        ``history`` continues the old one with a numbered record of this change
        (calib_core.history), from which undo and redo are replayed.
        """
        s = self.require()
        with self._file_lock():
            self._sync_from_disk()
            for cid, sensor, _new in updates:
                if sensor not in self.sensors(cid):
                    raise SessionError(s.manifest_path, f"capture {cid} has no sensor '{sensor}'")
            n = history.next_change_id(self.detections)
            items = [self._put(cid, sensor, new, n, "do", action, client) for cid, sensor, new in updates]
            return self._commit(Change(n, str(client), action, items), "detections")

    def _put(self, cid: str, sensor: str, new: dict | None, n: int, kind: str, action: str, client: str,
             of: int | None = None) -> tuple:
        """Replace one entry (under the file lock), appending a change record; None leaves an empty `auto` entry
        that asks for a fresh detection (its history, and so undo/redo, must survive)."""
        prev = copy.deepcopy(self.detections.get(cid, {}).get(sensor))
        new = copy.deepcopy(new) if new is not None else {"status": "auto", RESTORED_MISSING: True}
        rec = {"time": now_iso(), "action": action, "status": new.get("status"), "center": new.get("center"),
               "client": str(client), "change": n, "kind": kind, "before": history.content(prev)}
        if of is not None:
            rec["of"] = of
        new["history"] = list((prev or {}).get("history") or []) + [rec]
        self.detections.setdefault(cid, {})[sensor] = new
        return (cid, sensor, prev, copy.deepcopy(new))

    def _commit(self, ch: Change, kind: str) -> Change:
        save_detections(self.session, self.detections)
        self._det_sig = self._disk_sig()
        self.version += 1
        self._emit(kind)
        return ch

    def set_status(self, cid: str, status: str, client: str, sensors: list[str] | None = None) -> Change:
        """Accept or reject (``status``) the given sensors of a capture (all by default).

        Accepting needs a centre: a sensor without one is left out (an error if none has one).
        """
        if status not in ("accepted", "rejected", "auto"):
            raise ValueError(f"unknown status {status!r}")
        sensors = sensors or self.sensors(cid)
        updates = []
        for sensor in sensors:
            cur = self.entry(cid, sensor) or {}
            if status == "accepted" and cur.get("center") is None:
                continue
            if cur.get("status") == status:
                continue
            updates.append((cid, sensor, dict(cur, status=status)))
        if not updates:
            if status == "accepted" and not any((self.entry(cid, x) or {}).get("center") for x in sensors):
                raise SessionError(self.require().manifest_path,
                                   f"capture {cid}: nothing to accept (no detected centre; correct it by hand first)")
            raise SessionError(self.require().manifest_path, f"capture {cid} is already {status}")
        return self.apply(updates, client, {"accepted": "accept", "rejected": "reject", "auto": "reset"}[status])

    def correct(self, cid: str, sensor: str, entry: dict, client: str, action: str = "correct") -> Change:
        """Store an operator correction (a refit result or a hand-placed centre) as ``corrected``."""
        if entry.get("center") is None:
            raise SessionError(self.require().manifest_path, f"capture {cid} {sensor}: a correction needs a centre")
        return self.apply([(cid, sensor, dict(entry, status="corrected"))], client, action)

    def history_stacks(self) -> tuple[list, list]:
        """(done, undone) changes from detections.yaml (what Undo / Redo take next is last)."""
        with self._file_lock():
            self._sync_from_disk()
            return history.stacks(self.detections)

    def undo(self, client: str | None = None) -> Change:
        """Undo the session's latest change (whoever made it, in any earlier run)."""
        return self._step_history("undo", client)

    def redo(self, client: str | None = None) -> Change:
        """Redo the latest undone change (a new change after an undo clears the redo list)."""
        return self._step_history("redo", client)

    def _step_history(self, kind: str, client: str | None) -> Change:
        s = self.require()
        with self._file_lock():
            self._sync_from_disk()
            done, undone = history.stacks(self.detections)
            stack = done if kind == "undo" else undone
            if not stack:
                raise SessionError(detections_path(s), f"nothing to {kind}")
            ch = stack[-1]
            restore = []
            for cid, sensor, _rec in ch.items:
                cur = self.detections.get(cid, {}).get(sensor)
                rec, after = history.step_record(cur, ch.id, kind)
                if rec is None or {"status": cur.get("status"), "center": cur.get("center")} != after:
                    raise SessionError(detections_path(s),
                                       f"cannot {kind} '{ch.action}' on {cid}/{sensor}: it was changed since")
                restore.append((cid, sensor, rec.get("before")))
            n = history.next_change_id(self.detections)
            items = [self._put(cid, sensor, before, n, kind, f"{kind} {ch.action}", str(client), of=ch.id)
                     for cid, sensor, before in restore]
            return self._commit(Change(ch.id, ch.client, ch.action, items), "detections")

    def _same_session(self, session) -> None:
        if session is not None and session is not self.session:
            raise SessionError(session.manifest_path, "another session was opened meanwhile; result discarded")

    def merge_automatic(self, auto: dict, session=None) -> None:
        """Merge fresh automatic detections (operator entries are never overwritten).

        ``session``: the session they were computed for (refused if another one is open now).
        """
        s = self.require()
        with self._file_lock():
            self._same_session(session)
            self._sync_from_disk()
            auto_only = {cid: {k: e for k, e in sens.items() if e.get("status", "auto") == "auto"}
                         for cid, sens in auto.items()}
            old = self.detections
            self.detections = merge_auto(old, auto_only)
            for cid, sens in auto_only.items():  # a fresh detection continues the entry's change records
                for sensor in sens:
                    hist = (old.get(cid, {}).get(sensor) or {}).get("history")
                    if hist and sensor in self.detections.get(cid, {}):
                        self.detections[cid][sensor]["history"] = hist
            save_detections(s, self.detections)
            self._det_sig = self._disk_sig()
            self.version += 1
        self._emit("detections")

    def missing(self) -> list[str]:
        """Captures with a sensor that has no entry yet (to detect on load)."""
        s = self.require()
        with self.lock:
            return [c.id for c in s.captures
                    if any(x not in self.detections.get(c.id, {}) or self.detections[c.id][x].get(RESTORED_MISSING)
                           for x in self.sensors(c.id))]

    # ---- calibration -------------------------------------------------------
    def set_calibration(self, result: dict, session=None) -> Path:
        """Save exactly ``result`` (the solver's dict) to results/calibration.json.

        ``session``: the session it was computed for (refused if another one is open now).
        """
        s = self.require()
        path = calibration_path(s)
        with self.lock:
            self._same_session(session)
            save_calibration(path, result, root=s.root)
            self.calibration = result
            self.cal_version += 1
            self.version += 1
        self._emit("calibration")
        return path

    def snapshot(self) -> tuple[Session, dict, dict | None]:
        """A consistent copy of (session, detections, calibration) for worker threads."""
        with self.lock:
            return self.require(), copy.deepcopy(self.detections), copy.deepcopy(self.calibration)

    # ---- calibration lookups (data only; projection is calib_core.fusion's) ----
    def T_cam_sonar(self, cam: str):
        """(T_cam_sonar 4x4, range_scale s) of the current calibration, or None if uncalibrated.

        Camera-frame points are ``T_cam_sonar (X_cloud / s)`` (calib_core.solve.model).
        """
        import numpy as np

        with self.lock:
            cal = self.calibration
        c = (cal or {}).get("cameras", {}).get(cam)
        if not c or c.get("T_cam_sonar") is None:
            return None
        scale = c.get("range_scale", (cal or {}).get("range_scale", 1.0))
        if isinstance(scale, dict):
            scale = scale.get("value", 1.0)
        return np.asarray(c["T_cam_sonar"], float), float(scale or 1.0)

    def reprojected_uv(self, cid: str, cam: str):
        """Raw pixel of capture ``cid``'s sonar centre through the current calibration, or None.

        The one definition of a capture's residual: |image centre - this| (px), shown by every panel.
        """
        import numpy as np

        cal, son = self.T_cam_sonar(cam), (self.entry(cid, SENSOR_SONAR) or {}).get("center")
        if cal is None or son is None:
            return None
        key = (cid, cam, self.cal_version, tuple(son))
        with self.lock:
            if key in self._centres:
                return self._centres[key]
        T, s = cal
        P = T[:3, :3] @ (np.asarray(son, float) / s) + T[:3, 3]  # as the solver's residual (calib_core.solve.model)
        uv = self.camera(cam).distort((P[:2] / P[2])[None])[0] if P[2] > 1e-3 else None
        with self.lock:
            self._centres[key] = uv
            while len(self._centres) > 512:
                self._centres.popitem(last=False)
        return self._centres[key]

    def residual_px(self, cid: str, cam: str) -> float | None:
        """|image centre - reprojected sonar centre| (px) with the current calibration, or None."""
        import numpy as np

        e = self.entry(cid, cam) or {}
        if e.get("center") is None or e.get("status") == "rejected":
            return None
        uv = self.reprojected_uv(cid, cam)
        return None if uv is None else float(np.linalg.norm(np.asarray(e["center"], float) - uv))

    def flag_for(self, cid: str, sensor: str | None = None):
        """The newest diagnosis's flag on capture ``cid`` (and ``sensor``: a camera, or "sonar"), or None."""
        for f in list(self.flags):
            if f.capture == cid and (sensor is None or f.sensor in (sensor, "capture")):
                return f
        return None

