"""Run automatic detections over captures in parallel processes (deterministic results).

Results come back in the order of the task list whatever order the processes finish in, and
each detection is a pure function of its inputs, so the merged detections do not depend on
the number of processes. Progress is reported as tasks finish.

The pool uses a fork server (a clean process that imported the detectors once and forks the
workers): forking the caller itself can deadlock, since OpenCV's and BLAS's thread pools (and
the workbench's server threads) do not survive a fork. As with any spawn / fork-server pool, a
calling script needs an ``if __name__ == "__main__":`` guard; without one the pool breaks and
detection runs in process instead. Small sessions (fewer than ``MIN_POOL_TASKS`` detections)
run in process, where they finish sooner. ``SONARCAL_WORKERS`` overrides the process count
(1: in process).
"""

from __future__ import annotations

import os

_DATA = None  # the SessionData of this worker process (set by _init)


# Below this many tasks the pool costs more than it saves on a shared machine: its fork server
# imports the detectors again (~0.7 CPU-s) and every worker receives the session. A fresh
# `sonarcal calibrate` of 9 captures x 2 cameras at 1080p (28 tasks) on 2 cores
# (benchmarks/bench_calibrate_speed.py): 2.49 s in one process, 3.59 s in two at load 2.4-2.8;
# 2.43 s against 2.18 s at load 1.7-2.1.
MIN_POOL_TASKS = 40


def worker_count(n_tasks: int, workers: int | None = None) -> int:
    """Processes for ``n_tasks`` detections: ``workers``, else ``SONARCAL_WORKERS``, else one
    per core when there are at least :data:`MIN_POOL_TASKS` tasks (else 1: in process)."""
    if workers is None:
        env = os.environ.get("SONARCAL_WORKERS", "").strip()
        if env.isdigit() and int(env) > 0:
            workers = int(env)
        else:
            workers = (os.cpu_count() or 1) if n_tasks >= MIN_POOL_TASKS else 1
    return max(1, min(int(workers), n_tasks))


def _init(data) -> None:
    global _DATA
    _DATA = data
    try:
        import cv2

        cv2.setNumThreads(1)  # one process per core already
        # as the CLI does in its own process: OpenCV's decoder warnings would add lines to stderr
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR if os.environ.get("SONARCAL_DEBUG")
                                      else cv2.utils.logging.LOG_LEVEL_SILENT)
    except (ImportError, AttributeError):  # pragma: no cover
        pass


def _task(item):
    """(cid, sensor, entry) or (cid, sensor, SessionError parts): SessionError does not pickle.
    A sonar task carries the session's beam width (estimated after the pool started), an image
    task the file its camera's background model was saved to ("" when the camera has none)."""
    from calib_core.errors import SessionError
    from calib_core.detect.entries import detect_one

    cid, sensor, beam, background_file = item
    if beam is not None:
        _DATA.beam_width_deg = beam
    if background_file is not None and sensor not in _DATA.backgrounds:
        _DATA.backgrounds[sensor] = _load_background(background_file)
    try:
        return cid, sensor, detect_one(_DATA, cid, sensor)
    except SessionError as e:
        return cid, sensor, ("error", None if e.path is None else str(e.path), e.problem)


def _load_background(path: str):
    import numpy as np

    from calib_core.detect.image.detect import prepare_background

    return prepare_background(np.load(path)) if path else None


def _share_backgrounds(data, todo, folder: str) -> dict:
    """{camera: .npy file of its prepared background model, or "" when it has none}: each
    worker loads a model once instead of receiving every camera's (25 MB at 1080p) at start."""
    import numpy as np

    out = {}
    for k, cam in enumerate(sorted({sensor for _, sensor in todo if sensor != "sonar"})):
        bg = data.backgrounds.get(cam)
        out[cam] = "" if bg is None else os.path.join(folder, f"background{k}.npy")
        if bg is not None:
            np.save(out[cam], bg.image)
    return out


def _crop_task(cid, detections):
    """One capture's crop for the beam-width estimate (None when no sphere is found there)."""
    from calib_core.errors import SessionError
    from calib_core.detect.entries import beam_crop_of

    try:
        return beam_crop_of(_DATA, cid, detections)
    except SessionError:
        return None  # its own sonar task reports the problem


def _scan_task(crops):
    from calib_core.detect.entries import beam_width_from_crops

    return beam_width_from_crops(_DATA, crops)


def _cloud_readers(data, todo) -> list[str]:
    """open3d when sonar tasks will read compressed PCD clouds (the only kind numpy does not
    read; see :mod:`calib_core.io.cloud_binary`): imported once in the fork server rather than
    once in every worker (it takes about a second)."""
    from calib_core.io.cloud_binary import needs_open3d

    cids = {cid for cid, sensor in todo if sensor == "sonar"}
    return ["open3d"] if any(needs_open3d(data.session.capture(c).cloud_path) for c in cids) else []


def _prepare(data, todo) -> None:
    """Camera models and background models, computed once in the parent for every worker, one
    thread per camera (decoding and the median release the GIL)."""
    from concurrent.futures import ThreadPoolExecutor

    cams = sorted({sensor for _, sensor in todo if sensor != "sonar"})
    with ThreadPoolExecutor(max(1, min(len(cams), os.cpu_count() or 1))) as ex:
        list(ex.map(lambda cam: (data.camera(cam), data.background(cam)), cams))


def _unwrap(cid, sensor, out):
    from calib_core.errors import SessionError

    if isinstance(out, tuple) and out and out[0] == "error":
        raise SessionError(out[1], out[2])
    return cid, sensor, out


def run_detections(data, todo: list[tuple[str, str]], progress=None, workers: int | None = None,
                   beam_ids: list | None = None, beam_detections: dict | None = None) -> list:
    """[(capture_id, sensor, entry)] for every (capture_id, sensor) in ``todo``, in that order.

    With ``beam_ids``, the session's effective beam width is first estimated from those
    captures' clouds (``data.beam_width_deg`` is set) and the sonar detections use it; in a pool
    the image detections run meanwhile."""
    from concurrent.futures.process import BrokenProcessPool

    n = worker_count(len(todo) + (1 if beam_ids else 0), workers)
    if n > 1:
        try:
            return _run_pool(data, todo, progress, n, beam_ids or [], beam_detections or {})
        except (BrokenProcessPool, BrokenPipeError, EOFError):
            pass  # e.g. a calling script without an ``if __name__ == "__main__":`` guard: run in process
    return _run_in_process(data, todo, progress, beam_ids or [], beam_detections or {})


# images decoded ahead of their detection in a second thread (6 MB each at 1080p)
PREFETCH_AHEAD = 4


def _run_in_process(data, todo, progress, beam_ids: list, beam_detections: dict) -> list:
    """The detections in this process, in ``todo``'s order; the images (and background models)
    are decoded meanwhile in a second thread (:mod:`calib_core.prefetch`): on a second core the
    decoding (0.2 CPU-s of a fresh 9-capture 1080p calibrate) overlaps the sonar's work."""
    from calib_core.detect.entries import detect_one, prefetch_jobs, session_beam_width_shared
    from calib_core.prefetch import Prefetch

    with Prefetch(prefetch_jobs(data, todo), PREFETCH_AHEAD) as ahead:
        shared = {}  # the beam width's clouds and searches, for their own sonar detections
        if beam_ids:
            data.beam_width_deg, shared = session_beam_width_shared(data, beam_ids, beam_detections)
        out, cams = [], set()
        for i, (cid, sensor) in enumerate(todo):
            if progress:
                progress(i, len(todo), f"{cid} {sensor}")
            image, cloud = None, shared.pop(cid, None) if sensor == "sonar" else None
            if sensor != "sonar":
                if sensor not in cams:
                    cams.add(sensor)
                    ahead.take(("background", sensor))
                image = ahead.take((cid, sensor))
            out.append((cid, sensor, detect_one(data, cid, sensor, image_rgb=image, cloud=cloud)))
    return out


def _run_pool(data, todo, progress, n: int, beam_ids: list, beam_detections: dict) -> list:
    """The beam width's crops start while this process prepares the background models."""
    import dataclasses
    import multiprocessing as mp
    import tempfile
    from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
    from multiprocessing import forkserver

    from calib_core.detect.entries import beam_capture_ids

    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(["calib_core.pipeline", "calib_core.detect.image.detect", "calib_core.detect.sonar.detect",
                                *_cloud_readers(data, todo)])
    forkserver.ensure_running()  # the server imports the detectors on the other core while we prepare
    results: list = [None] * len(todo)
    if progress:
        progress(0, len(todo), f"detecting in {n} processes")
    later = [k for k, t in enumerate(todo) if beam_ids and t[1] == "sonar"]
    crop_ids = beam_capture_ids(beam_ids) if beam_ids else []
    worker_data = dataclasses.replace(data, backgrounds={})
    with tempfile.TemporaryDirectory(prefix="sonarcal-bg-") as tmp, ThreadPoolExecutor(1) as thread, \
            ProcessPoolExecutor(n, mp_context=ctx, initializer=_init, initargs=(worker_data,)) as ex:
        try:
            prepared = thread.submit(_prepare, data, todo)  # while the fork server imports and the crops run
            q = _Queue(ex, n + 1)
            # the beam width's crops first (its scan and then every sonar task wait for them)
            q.add([(("crop", cid), _crop_task, (cid, beam_detections)) for cid in crop_ids])
            prepared.result()
            files = _share_backgrounds(data, todo, tmp)
            q.add([(k, _task, ((*t, None, files.get(t[1])),)) for k, t in enumerate(todo) if k not in later])
            _drain(q, data, todo, progress, results, later, crop_ids, n)
        except BaseException:  # e.g. Cancelled from the progress callback: queued tasks are dropped
            ex.shutdown(wait=True, cancel_futures=True)
            raise
    return [_unwrap(*r) for r in results]


class _Queue:
    """The pool's work in priority order, at most ``limit`` tasks handed to the pool at a time
    (the pool itself runs them first come, first served): the beam width's crops first, its scan
    as soon as the crops are in, then the sonar tasks waiting for the width, the images last, as
    nothing waits for them."""

    def __init__(self, ex, limit: int):
        self.ex, self.limit, self.waiting, self.running = ex, limit, [], {}

    def add(self, items: list, first: bool = False) -> None:
        """Queue ``[(key, function, args)]``, ahead of the waiting tasks with ``first``."""
        self.waiting = [*items, *self.waiting] if first else [*self.waiting, *items]
        self.fill()

    def fill(self) -> None:
        while self.waiting and len(self.running) < self.limit:
            key, fn, args = self.waiting.pop(0)
            self.running[self.ex.submit(fn, *args)] = key

    def finished(self, timeout: float):
        from concurrent.futures import FIRST_COMPLETED, wait

        done, _ = wait(self.running, timeout=timeout, return_when=FIRST_COMPLETED)
        return [(self.running.pop(f), f.result()) for f in done]


def _drain(q: _Queue, data, todo, progress, results: list, later: list, crop_ids: list, n: int) -> None:
    """Collect the results as they finish; queue the scan when the crops are in, the sonar tasks
    when the beam width is known."""
    crops: dict = {}
    done, label = 0, f"detecting in {n} processes"
    while q.running:
        finished = q.finished(0.5)
        if not finished and progress:
            progress(done, len(todo), label)  # also lets the caller cancel between results
        for k, out in finished:
            if isinstance(k, tuple):
                crops[k[1]] = out
                if len(crops) == len(crop_ids):
                    q.add([(-1, _scan_task, ([crops[c] for c in crop_ids],))], first=True)
            elif k == -1:
                data.beam_width_deg = out
                beam = data.effective_beam_width_deg
                q.add([(j, _task, ((*todo[j], beam, None),)) for j in later], first=True)
            else:
                results[k] = out
                done, label = done + 1, f"{out[0]} {out[1]}"
                if progress:
                    progress(done, len(todo), label)
        q.fill()
