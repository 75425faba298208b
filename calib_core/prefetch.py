"""Work done ahead in one background thread, taken back in order (decoding images while the
sonar detections run).

JPEG/PNG decoding and large numpy operations release the GIL, so on a second core they cost
the calling thread almost nothing; the detections themselves stay in the calling thread, in
their order, so results do not change. At most ``ahead`` results wait at a time (a 1080p
frame is 6 MB), and a job's exception is raised where its result is taken, as if the job had
run there.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Hashable


class Prefetch:
    """Run ``jobs`` [(key, fn)] in order in one background thread; :meth:`take` returns the next
    job's result (raises its exception). Use as a context manager: leaving it stops the thread
    (jobs not started are dropped)."""

    def __init__(self, jobs: list[tuple[Hashable, Callable]], ahead: int = 4):
        self._jobs = list(jobs)
        self._queue: queue.Queue = queue.Queue(maxsize=max(1, int(ahead)))
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="sonarcal-prefetch", daemon=True)

    def __enter__(self) -> Prefetch:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        while self._thread.is_alive():  # unblock a put() waiting for room
            try:
                self._queue.get(timeout=0.05)
            except queue.Empty:
                pass
        self._thread.join()

    def _run(self) -> None:
        for key, fn in self._jobs:
            if self._stop.is_set():
                return
            try:
                item = (key, True, fn())
            except BaseException as e:  # handed to the taker, raised there
                item = (key, False, e)
            while not self._stop.is_set():
                try:
                    self._queue.put(item, timeout=0.05)
                    break
                except queue.Full:
                    pass

    def take(self, key: Hashable):
        """The result of the next job, which must be ``key`` (jobs are taken in their order)."""
        got, ok, value = self._queue.get()
        if got != key:
            raise RuntimeError(f"prefetch taken out of order: {key!r} asked, {got!r} next")
        if not ok:
            raise value
        return value
