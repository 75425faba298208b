"""Write a new session into a hidden temporary folder beside the target, then rename it.

Nothing half-written: on any error the temporary folder is removed and the target is
untouched; the target must not exist or be an empty folder.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np

from calib_core.errors import SessionError
from calib_core.io.atomic import atomic_write_yaml
from calib_core.io.clouds import Cloud, save_cloud
from calib_core.io.images import save_image
from calib_core.io.intrinsics import save_intrinsics_ros


class StagedSession:
    """``with StagedSession(target) as st: st.cloud(...); st.image(...); st.manifest(...)``."""

    def __init__(self, target: str | Path):
        self.target = Path(target).absolute()
        if self.target.exists() and (not self.target.is_dir() or any(self.target.iterdir())):
            raise SessionError(self.target, "output exists and is not an empty folder (choose a new --out)")
        self.root: Path | None = None
        self._manifest = False

    def __enter__(self) -> "StagedSession":
        self.target.parent.mkdir(parents=True, exist_ok=True)
        self.root = Path(tempfile.mkdtemp(prefix=f".{self.target.name}.importing-", dir=self.target.parent))
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None and self._manifest:
            if self.target.is_dir():
                self.target.rmdir()  # empty (checked above)
            self.root.rename(self.target)
        else:
            shutil.rmtree(self.root, ignore_errors=True)

    def cloud(self, cid: str, points_m: np.ndarray, intensity: np.ndarray | None) -> str:
        rel = f"clouds/{cid}.ply"
        save_cloud(self.root / rel, Cloud(points_m, intensity))
        return rel

    def image(self, folder: str, cam: str, stem: str, image_rgb: np.ndarray) -> str:
        rel = f"{folder}/{cam}/{stem}.png"
        save_image(self.root / rel, image_rgb)
        return rel

    def intrinsics(self, cam: str, model) -> str:
        rel = f"intrinsics/{cam}.yaml"
        save_intrinsics_ros(self.root / rel, model, cam)
        return rel

    def copy_intrinsics(self, cam: str, src: Path) -> str:
        from calib_core.io.intrinsics import load_intrinsics

        return self.intrinsics(cam, load_intrinsics(src))

    def manifest(self, data: dict) -> None:
        atomic_write_yaml(self.root / "session.yaml", data)
        self._manifest = True
