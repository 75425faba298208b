"""Small shell helpers shared by the panels: error notices, a refresh thread, a job runner."""

from __future__ import annotations

import functools
import logging
import threading
import time
import traceback
from typing import Callable

import numpy as np
import viser
import viser.transforms as vtf

from calib_core.errors import Cancelled, SessionError

log = logging.getLogger("sonarcal.app")


def error_text(exc: BaseException) -> str:
    if isinstance(exc, SessionError):
        return str(exc)
    return f"{type(exc).__name__}: {exc}"


def notify(server: viser.ViserServer, client, title: str, body: str, color: str = "red", seconds: float = 8.0) -> None:
    """Show a notification in ``client``'s page (every page when client is None)."""
    targets = [client] if client is not None else list(server.get_clients().values())
    for c in targets:
        try:
            c.add_notification(title, body, auto_close_seconds=seconds, color=color, with_close_button=True)
        except Exception:  # a client that just left: nothing to tell
            log.debug("notification to a gone client dropped", exc_info=True)


def guarded(server: viser.ViserServer, title: str = "Action failed"):
    """Decorator for GUI/scene callbacks: any exception becomes a notification, never a crash."""

    def deco(fn: Callable):
        @functools.wraps(fn)
        def wrapper(event=None, *a, **k):
            try:
                return fn(event, *a, **k)
            except Exception as e:  # the server must survive any bad action or file
                if not isinstance(e, SessionError):
                    log.error("callback %s failed:\n%s", fn.__name__, traceback.format_exc())
                notify(server, getattr(event, "client", None), title, error_text(e))
                return None

        return wrapper

    return deco


def client_tag(event) -> str:
    cid = getattr(event, "client_id", None)
    return f"browser-{cid}" if cid is not None else "server"


def pose_wxyz_position(T_parent_child: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """viser node pose (wxyz quaternion, position) of a 4x4 transform child->parent."""
    T = np.asarray(T_parent_child, float)
    return vtf.SO3.from_matrix(T[:3, :3]).wxyz, T[:3, 3].copy()


class Refresher:
    """One thread applies scene/GUI refreshes in order, coalescing bursts of changes.

    ``mark(kind)`` asks for a refresh; handlers registered with ``on(kind, fn)`` run in the
    refresh thread. ``wait_idle()`` blocks until every pending refresh has run (tests,
    benchmarks).

    Handlers registered with ``heavy=True`` load or send big data (clouds, images). In each
    batch they run after the light ones (the review table never waits for an image), and
    while the refresher is held (:meth:`hold`, the first page loading) they are owed and run
    on :meth:`release`.
    """

    _OWED = "owed"  # the pseudo-kind under which held heavy handlers run on release

    def __init__(self, on_error: Callable[[str, BaseException], None]):
        self._handlers: dict[str, list[Callable[[], None]]] = {}
        self._heavy: set = set()
        self._owed: list[Callable[[], None]] = []
        self._holding = False
        self._dirty: list[str] = []
        self._cv = threading.Condition()
        self._busy = False
        self._stop = False
        self._on_error = on_error
        self._thread = threading.Thread(target=self._run, name="workbench-refresh", daemon=True)
        self._thread.start()

    def on(self, kind: str, fn: Callable[[], None], heavy: bool = False) -> None:
        self._handlers.setdefault(kind, []).append(fn)
        if heavy:
            self._heavy.add(fn)

    def mark(self, *kinds: str) -> None:
        with self._cv:
            for k in kinds:
                if k not in self._dirty:
                    self._dirty.append(k)
            self._cv.notify_all()

    def hold(self) -> None:
        """Heavy handlers wait (are owed) until :meth:`release`."""
        with self._cv:
            self._holding = True

    def release(self) -> None:
        """Run the heavy handlers owed since :meth:`hold`; from now on they run as asked."""
        with self._cv:
            self._holding = False
            if self._owed and self._OWED not in self._dirty:
                self._dirty.append(self._OWED)
            self._cv.notify_all()

    @property
    def holding(self) -> bool:
        return self._holding

    def wait_idle(self, timeout: float = 30.0, owed: bool = True) -> bool:
        """True once nothing is pending; with ``owed``, held heavy handlers too (they wait for a
        release)."""
        end = time.monotonic() + timeout
        with self._cv:
            while self._dirty or self._busy or (owed and self._owed):
                left = end - time.monotonic()
                if left <= 0:
                    return False
                self._cv.wait(left)
        return True

    def stop(self) -> None:
        with self._cv:
            self._stop = True
            self._owed.clear()
            self._cv.notify_all()

    def _batch(self, kinds: list[str]) -> list[tuple[str, Callable[[], None]]]:
        """The handlers of one batch, each once: light ones first, then heavy ones (owed instead
        while holding)."""
        light, heavy, seen = [], [], set()
        with self._cv:
            for kind in kinds:
                fns = self._owed[:] if kind == self._OWED else self._handlers.get(kind, [])
                if kind == self._OWED:
                    self._owed.clear()
                for fn in fns:
                    if fn in seen:
                        continue
                    seen.add(fn)
                    if fn not in self._heavy:
                        light.append((kind, fn))
                    elif self._holding:
                        if fn not in self._owed:
                            self._owed.append(fn)
                    else:
                        heavy.append((kind, fn))
        return light + heavy

    def _run(self) -> None:
        while True:
            with self._cv:
                while not self._dirty and not self._stop:
                    self._cv.wait()
                if self._stop:
                    return
                kinds, self._dirty = self._dirty, []
                self._busy = True
            try:
                for kind, fn in self._batch(kinds):
                    try:
                        fn()
                    except Exception as e:  # keep refreshing the other panels
                        log.error("refresh %s failed:\n%s", kind, traceback.format_exc())
                        self._on_error(kind, e)
            finally:
                with self._cv:
                    self._busy = False
                    self._cv.notify_all()


class JobRunner:
    """Runs one long job (detection, solve) at a time in a worker thread with progress."""

    def __init__(self, on_progress: Callable[[str, float, str], None], on_error: Callable[[str, BaseException], None]):
        self._lock = threading.Lock()
        self.running: str | None = None
        self._thread: threading.Thread | None = None
        self._on_progress = on_progress
        self._on_error = on_error
        self._cancel = threading.Event()

    def start(self, name: str, fn: Callable[[Callable[[int, int, str], None]], None]) -> None:
        with self._lock:
            if self._cancel.is_set():
                return  # shutting down
            if self.running is not None:
                raise RuntimeError(f"'{self.running}' is still running; wait for it to finish")
            self.running = name

        def progress(done: int, total: int, label: str) -> None:
            if self._cancel.is_set():
                raise Cancelled(f"'{name}' cancelled")
            self._on_progress(name, 100.0 * done / max(total, 1), label)

        def run() -> None:
            try:
                self._on_progress(name, 0.0, "starting")
                fn(progress)
            except Cancelled:
                log.info("job %s cancelled", name)
            except Exception as e:  # reported in the page, the server lives on
                if not isinstance(e, SessionError):
                    log.error("job %s failed:\n%s", name, traceback.format_exc())
                self._on_error(name, e)
            finally:
                with self._lock:
                    self.running = None
                self._on_progress(name, -1.0, "done")

        self._thread = threading.Thread(target=run, name=f"job-{name}", daemon=True)
        self._thread.start()

    def cancel(self, timeout: float = 10.0) -> None:
        """Ask the running job to stop at its next progress step (no new job starts), and wait
        up to ``timeout`` s for it: what a job writes, it writes whole, so nothing is half-done."""
        self._cancel.set()
        self.join(timeout)

    def join(self, timeout: float | None = None) -> None:
        t = self._thread
        if t is not None:
            t.join(timeout)
