"""Shared by the bag and the video importers: options, per-scan output and the manifest.

A finished scan becomes a capture (its cloud as binary PLY, the kept frame of each camera as
PNG, its motion entry); the manifest adds the optional ``source`` and ``target_motion``
blocks (docs/architecture.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calib_core.ingest.motion import NS, TOLERANCE_M, TOLERANCE_PX
from calib_core.ingest.scans import ScanWindow
from calib_core.ingest.staging import StagedSession

FORMAT = "sonar-camera-session/1"
MAX_BACKGROUND_FRAMES = 8


@dataclass
class ImportOptions:
    """What the user chose (CLI flags); ``intrinsics`` maps camera name -> intrinsics file, and
    ``intrinsics_entry`` camera name -> the entry of a Kalibr camchain that is that camera."""

    diameter_m: float
    sonar_topic: str | None = None
    camera_topics: list[str] | None = None
    intrinsics: dict[str, Path] = field(default_factory=dict)
    intrinsics_entry: dict[str, str] = field(default_factory=dict)
    split: str = "auto"
    gap_seconds: float | None = None
    scan_seconds: float | None = None
    background_window_s: tuple[float, float] | None = None
    tolerance_px: float = TOLERANCE_PX
    tolerance_m: float = TOLERANCE_M
    id_prefix: str = "p"
    drop_moved: bool = False
    median: int = 1
    name: str | None = None
    sonar_model: str | None = None


@dataclass
class ImportResult:
    out: Path
    captures: list[str]
    moved: list[str]
    skipped: list[str]


class Assembler:
    """Collects captures into a staged session and writes the manifest at the end."""

    def __init__(self, st: StagedSession, opts: ImportOptions, windows: list[ScanWindow], t0_ns: int,
                 ids: list[str] | None = None):
        self.st, self.opts, self.windows, self.t0, self.ids = st, opts, windows, t0_ns, ids
        self.captures, self.source_caps, self.motion = [], {}, {}
        self.moved, self.skipped = [], []
        self.done: set[int] = set()
        self.width = max(2, len(str(len(windows))))

    def capture_id(self, i: int) -> str:
        if self.ids is not None:
            return self.ids[i]
        return f"{self.opts.id_prefix}{i + 1:0{self.width}d}"

    def rel_s(self, t_ns: int) -> float:
        return round((t_ns - self.t0) / NS, 4)

    def finish_scan(self, i: int, points: list[np.ndarray], inten: list[np.ndarray] | None,
                    frames: dict[str, np.ndarray], motion: dict | None, n_messages: int) -> None:
        cid, w = self.capture_id(i), self.windows[i]
        info = {"start_s": self.rel_s(w.start_ns), "end_s": self.rel_s(w.end_ns), "clouds": n_messages,
                "points": int(sum(len(p) for p in points))}
        self.source_caps[cid] = info
        if not points or info["points"] == 0 or not frames:
            self._skip(cid, "no sonar points" if info["points"] == 0 else "no camera frame during the scan")
            return
        if motion is not None:
            self.motion[cid] = motion
            if motion["moved"]:
                self.moved.append(cid)
                if self.opts.drop_moved:
                    self._skip(cid, "target moved during the scan")
                    return
        pts = np.concatenate(points)
        it = np.concatenate(inten) if inten is not None and len(inten) == len(points) else None
        cloud = self.st.cloud(cid, pts, it)
        images = {cam: self.st.image("images", cam, cid, img) for cam, img in sorted(frames.items())}
        self.captures.append({"id": cid, "cloud": cloud, "images": images})

    def _skip(self, cid: str, reason: str) -> None:
        self.source_caps[cid]["skipped"] = reason
        self.skipped.append(cid)

    def manifest(self, cameras: dict[str, dict], source: dict, name: str, stereo: dict | None = None) -> ImportResult:
        if not self.captures:
            from calib_core.errors import SessionError

            raise SessionError(source.get("path"), "no capture could be made: no scan had both sonar points "
                               f"and camera frames ({len(self.skipped)} scans skipped)")
        source = dict(source, captures=self.source_caps)
        data = {"format": FORMAT, "name": self.opts.name or name,
                "sphere": {"diameter": float(self.opts.diameter_m)},
                "sonar": {"model": self.opts.sonar_model} if self.opts.sonar_model else {},
                "cameras": cameras, "captures": self.captures, "source": source,
                "target_motion": {"tolerance_px": self.opts.tolerance_px, "tolerance_m": self.opts.tolerance_m,
                                  "captures": self.motion}}
        if not data["sonar"]:
            del data["sonar"]
        if stereo:
            data["stereo"] = stereo
            source["stereo_from"] = "/tf_static"
        self.st.manifest(data)
        return ImportResult(self.st.target, [c["id"] for c in self.captures], self.moved, self.skipped)
