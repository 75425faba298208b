"""Work done ahead in a second thread (calib_core.prefetch) and the in-process detections that use
it: results in order, a job's error raised where its result is taken, nothing left running."""

from __future__ import annotations

import threading
import time

import pytest
import yaml

from calib_core.errors import SessionError
from calib_core.prefetch import Prefetch


def test_results_in_order_and_errors_where_taken():
    def boom():
        raise SessionError("x.png", "image file is empty (0 bytes)")

    with Prefetch([("a", lambda: 1), ("b", boom), ("c", lambda: 3)], ahead=1) as p:
        assert p.take("a") == 1
        with pytest.raises(SessionError, match="empty"):
            p.take("b")
        assert p.take("c") == 3


def test_at_most_ahead_results_wait_and_leaving_stops_the_thread():
    started = []

    def job(k):
        started.append(k)
        return k

    with Prefetch([(k, lambda k=k: job(k)) for k in range(20)], ahead=2) as p:
        time.sleep(0.3)
        assert len(started) <= 3  # 2 waiting, one more done and waiting for room
        assert p.take(0) == 0
    n = len(started)
    time.sleep(0.1)
    assert len(started) == n < 20
    assert not any(t.name == "sonarcal-prefetch" for t in threading.enumerate())


def test_taken_out_of_order_is_refused():
    with Prefetch([("a", lambda: 1)]) as p, pytest.raises(RuntimeError, match="out of order"):
        p.take("b")


def test_a_bad_image_fails_the_run_as_without_the_prefetch(make_session, tmp_path):
    """A corrupt image among the captures: the same one-line error as detecting one by one."""
    from calib_core.detections import load_detections
    from calib_core.pipeline import SessionData, detect_session
    from calib_core.session import load_session

    root = make_session(tmp_path, n_captures=4, cameras=("cam1", "cam2"), background=True)
    man = yaml.safe_load((root / "session.yaml").read_text())
    bad = root / man["captures"][2]["images"]["cam2"]
    bad.write_bytes(bad.read_bytes()[:40])
    s = load_session(root)
    with pytest.raises(SessionError) as e:
        detect_session(SessionData(s), load_detections(s), workers=1)
    assert e.value.path is not None and str(e.value.path).endswith(bad.name)
    assert not any(t.name == "sonarcal-prefetch" for t in threading.enumerate())
