"""Write a new session into a hidden temporary folder beside the target, then rename it.

Nothing half-written: on any error the temporary folder is removed and the target is
untouched; the target must not exist or be an empty folder.
"""

from __future__ import annotations

import shutil
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import cv2
import numpy as np

from calib_core.errors import SessionError
from calib_core.io.atomic import atomic_write_yaml
from calib_core.io.clouds import Cloud, save_cloud
from calib_core.io.atomic import atomic_write_bytes
from calib_core.io.intrinsics import save_intrinsics_ros

MAX_PENDING = 4
PNG_LEVEL = 1


def _write_png(path: Path, image_rgb: np.ndarray) -> None:
    ok, buf = cv2.imencode(".png", cv2.cvtColor(image_rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_PNG_COMPRESSION, PNG_LEVEL])
    if not ok:
        raise SessionError(path, "cannot encode image")
    atomic_write_bytes(path, buf.tobytes())


class StagedSession:
    """``with StagedSession(target) as st: st.cloud(...); st.image(...); st.manifest(...)``."""

    def __init__(self, target: str | Path):
        self.target = Path(target).absolute()
        if self.target.exists() and (not self.target.is_dir() or any(self.target.iterdir())):
            raise SessionError(self.target, "output exists and is not an empty folder (choose a new --out)")
        self.root: Path | None = None
        self._manifest = False
        self._pool = ThreadPoolExecutor(max_workers=1)
        self._pending: list = []

    def __enter__(self) -> "StagedSession":
        self.target.parent.mkdir(parents=True, exist_ok=True)
        self.root = Path(tempfile.mkdtemp(prefix=f".{self.target.name}.importing-", dir=self.target.parent))
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        err = None
        try:
            for f in self._pending:
                f.result()  # an error writing a frame fails the import
        except BaseException as e:
            err = e
        finally:
            self._pool.shutdown(wait=True)
        if exc_type is None and err is None and self._manifest:
            if self.target.is_dir():
                self.target.rmdir()  # empty (checked above)
            self.root.rename(self.target)
            return
        shutil.rmtree(self.root, ignore_errors=True)
        if err is not None and exc_type is None:
            raise err

    def cloud(self, cid: str, points_m: np.ndarray, intensity: np.ndarray | None) -> str:
        rel = f"clouds/{cid}.ply"
        save_cloud(self.root / rel, Cloud(points_m, intensity))
        return rel

    def image(self, folder: str, cam: str, stem: str, image_rgb: np.ndarray) -> str:
        """PNG (fast compression: noisy camera frames barely compress), encoded and written by a
        background thread while the bag is read on; at most MAX_PENDING frames wait."""
        rel = f"{folder}/{cam}/{stem}.png"
        while len(self._pending) >= MAX_PENDING:
            self._pending.pop(0).result()
        self._pending.append(self._pool.submit(_write_png, self.root / rel, image_rgb))
        return rel

    def intrinsics(self, cam: str, model) -> str:
        rel = f"intrinsics/{cam}.yaml"
        save_intrinsics_ros(self.root / rel, model, cam)
        return rel

    def manifest(self, data: dict) -> None:
        atomic_write_yaml(self.root / "session.yaml", data)
        self._manifest = True
