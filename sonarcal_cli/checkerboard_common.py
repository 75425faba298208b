"""Shared by ``sonarcal intrinsics`` and ``sonarcal stereo``: loading checkerboard images, checks."""

from __future__ import annotations

import math

from calib_core.errors import SessionError


def load_images(paths):
    """[(name, RGB image)] for [(name, path)]."""
    from calib_core.io.images import load_image

    return [(n, load_image(p)) for n, p in paths]


def check_square(v: float) -> None:
    if not (math.isfinite(v) and 0 < v < 1.0):
        raise SessionError(None, f"--square {v} must be the square size in metres (e.g. 0.025)")
