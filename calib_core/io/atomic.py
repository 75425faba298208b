"""Atomic file writes: write a temporary file beside the target, fsync, rename.

A reader (or a crash at any moment) sees either the old file or the new one,
never a half-written one.
"""

from __future__ import annotations

import json
import os
import stat
import tempfile
import time
from pathlib import Path

import yaml


STALE_TEMP_S = 600.0  # temp files older than this are leftovers of a killed writer


def _umask() -> int:
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    old = os.umask(0o022)  # portable fallback (read once, at import)
    os.umask(old)
    return old


_UMASK = _umask()


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (same-folder temp file + os.replace).

    The temp file is ``.<name>.<random>.tmp`` beside the target (hidden, and no loader
    suffix, so loaders skip it). The new file keeps the old file's permissions (or gets the
    usual umask-based ones), not mkstemp's 0600. Temp files left by a killed writer are
    removed by a later write to the same file once they are older than STALE_TEMP_S.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        mode = stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        mode = 0o666 & ~_UMASK
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            os.fchmod(f.fileno(), mode)
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    try:  # make the rename itself durable
        dfd = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    except OSError:
        pass
    _sweep_stale_temps(path)


def _sweep_stale_temps(path: Path) -> None:
    """Delete old ``.<name>.*.tmp`` files beside ``path`` (left by a writer that was killed)."""
    prefix, now = f".{path.name}.", time.time()
    try:
        for entry in os.scandir(path.parent):
            if entry.name.startswith(prefix) and entry.name.endswith(".tmp") and entry.is_file(follow_symlinks=False):
                try:
                    if now - entry.stat(follow_symlinks=False).st_mtime > STALE_TEMP_S:
                        os.unlink(entry.path)
                except OSError:
                    pass
    except OSError:
        pass


def atomic_write_text(path: str | Path, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


class _NoAliasDumper(getattr(yaml, "CSafeDumper", yaml.SafeDumper)):
    """Safe YAML without anchors/aliases: a shared sub-tree is written out in full."""

    def ignore_aliases(self, data):
        return True


def atomic_write_yaml(path: str | Path, data) -> None:
    """Safe YAML (libyaml's emitter when present: same YAML, several times faster), no aliases."""
    atomic_write_text(path, yaml.dump(data, Dumper=_NoAliasDumper, sort_keys=False, default_flow_style=None,
                                      allow_unicode=True))


def atomic_write_json(path: str | Path, data) -> None:
    atomic_write_text(path, json.dumps(data, indent=2) + "\n")
