"""Cut a sonar message stream into scans (time windows), from the message times alone.

Rules (``split``):
- ``message``: every PointCloud2 is one whole scan; it covers the time since the previous one
  (the first: one median interval before it), or ``scan_seconds`` before it when given.
- ``gap``: slices of a pan are accumulated; a scan ends where the stream pauses longer than
  ``gap_seconds`` (default: the larger of 1 s and 3 median intervals). With ``scan_seconds``
  each such run is further cut into windows that long.
- ``auto``: ``gap`` when the stream has such pauses or ``scan_seconds`` is given; else
  ``message`` when messages come 2 s or more apart (evenly spaced whole scans), else one scan.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

NS = 1_000_000_000
SPLITS = ("auto", "gap", "message")
WHOLE_SCAN_INTERVAL_S = 2.0
GAP_FACTOR = 3.0


@dataclass(frozen=True)
class ScanWindow:
    """One scan: messages with ``start_ns <= t <= end_ns`` belong to it (times in bag ns)."""

    start_ns: int
    end_ns: int
    n_messages: int

    @property
    def mid_ns(self) -> int:
        return (self.start_ns + self.end_ns) // 2


def split_scans(times_ns, split: str = "auto", gap_seconds: float | None = None,
                scan_seconds: float | None = None) -> tuple[list[ScanWindow], str]:
    """Scan windows for sorted message times; also a one-line description of the rule used."""
    t = np.sort(np.asarray(times_ns, dtype=np.int64))
    if split not in SPLITS:
        raise ValueError(f"unknown split {split!r}; use one of {SPLITS}")
    if len(t) == 0:
        return [], "no sonar messages"
    dt = np.diff(t) / NS
    med = float(np.median(dt)) if len(dt) else 0.0
    gap = gap_seconds if gap_seconds is not None else max(1.0, GAP_FACTOR * med)
    if split == "auto":
        paused = bool(len(dt)) and bool((dt > gap).any())
        split = "gap" if paused or scan_seconds or med < WHOLE_SCAN_INTERVAL_S else "message"
    if split == "message":
        return _per_message(t, med, scan_seconds), "one PointCloud2 per scan"
    runs = np.split(t, np.flatnonzero(dt > gap) + 1)
    out = []
    for run in runs:
        out += _cut(run, scan_seconds) if scan_seconds else [ScanWindow(int(run[0]), int(run[-1]), len(run))]
    rule = f"slices accumulated, split at pauses > {gap:.2f} s"
    return out, rule + (f" and every {scan_seconds:g} s" if scan_seconds else "")


def _per_message(t: np.ndarray, med: float, scan_seconds: float | None) -> list[ScanWindow]:
    out = []
    for i, ti in enumerate(t):
        if scan_seconds:
            start = ti - int(scan_seconds * NS)
        else:
            start = t[i - 1] + 1 if i > 0 else ti - int(med * NS)
        out.append(ScanWindow(int(start), int(ti), 1))
    return out


def _cut(run: np.ndarray, scan_seconds: float) -> list[ScanWindow]:
    step = int(scan_seconds * NS)
    k = (run - run[0]) // step
    out = []
    for j in np.unique(k):
        sel = run[k == j]
        out.append(ScanWindow(int(sel[0]), int(sel[-1]), len(sel)))
    return out


def scan_index(windows: list[ScanWindow], t_ns: int) -> int:
    """Index of the scan whose window holds ``t_ns``, or -1."""
    for i, w in enumerate(windows):  # tens of scans: a linear scan is fine
        if w.start_ns <= t_ns <= w.end_ns:
            return i
    return -1
