"""Confine writes to the session folder: resolve the target before writing.

Every file the tool writes into a session (detections.yaml, results/calibration.json,
the report, exports) goes through :func:`confine_write`. The folder the file goes into is
resolved (every symlink on the way followed) and must lie inside the resolved session
folder; a target that is itself a symlink must point inside it too. So a ``results``
symlink to a folder elsewhere is refused instead of written through.

A path the user names explicitly on the command line (``--out``) that lies outside the
session is the user's choice and is left alone (``explicit=True``); written inside the
session, it is checked like any other.
"""

from __future__ import annotations

import os
from pathlib import Path

from calib_core.errors import SessionError


def _inside(root: Path, p: Path) -> bool:
    return p == root or root in p.parents


def confine_write(root, path, explicit: bool = False) -> Path:
    """Return ``path`` if writing it stays inside ``root``; raise SessionError otherwise."""
    root_r = Path(root).resolve()
    p = Path(path)
    lexical = Path(os.path.normpath(p if p.is_absolute() else Path.cwd() / p))
    if explicit and not _inside(Path(os.path.normpath(Path(root).absolute())), lexical) and not _inside(root_r, lexical):
        return p
    try:
        parent = lexical.parent.resolve()
        target = parent / lexical.name
        final = target.resolve() if target.is_symlink() else target
    except (OSError, RuntimeError):
        raise SessionError(p, "cannot resolve the output path (symlink loop or bad name)") from None
    if not _inside(root_r, parent) or not _inside(root_r, final) or final == root_r:
        raise SessionError(p, f"refused: this path leads outside the session folder {root_r} (through a symlink "
                              "or '..')")
    return p
