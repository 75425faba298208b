"""Safe unpacking of a zipped session uploaded from the browser (pure Python).

Refuses absolute paths, drive letters, ``..`` escapes, symlinks and other special
entries, more than ``max_files`` members and more than ``max_unpacked_bytes`` once
unpacked (zip bombs), checking the bytes actually written, not the sizes the archive
claims. Nothing inside an upload is ever executed.
"""

from __future__ import annotations

import io
import shutil
import stat
import tempfile
import zipfile
from pathlib import Path, PurePosixPath

from calib_core.errors import SessionError

MAX_UPLOAD_BYTES = 200 * 1024 * 1024
MAX_UNPACKED_BYTES = 1024 * 1024 * 1024
MAX_FILES = 20000


def _safe_member_path(name: str, where: Path) -> PurePosixPath:
    if "\x00" in name:
        raise SessionError(where, "archive entry name holds a NUL character")
    norm = name.replace("\\", "/")
    if norm.startswith("/") or (len(norm) > 1 and norm[1] == ":"):
        raise SessionError(where, f"archive entry '{name}' has an absolute path")
    p = PurePosixPath(norm)
    if any(part == ".." for part in p.parts):
        raise SessionError(where, f"archive entry '{name}' leaves the session folder ('..')")
    return p


def safe_unpack_zip(data: bytes, dest_parent: Path, label: str = "upload.zip",
                    max_upload_bytes: int = MAX_UPLOAD_BYTES,
                    max_unpacked_bytes: int = MAX_UNPACKED_BYTES,
                    max_files: int = MAX_FILES) -> Path:
    """Unpack a zipped session into a new folder under ``dest_parent``.

    Returns the folder holding ``session.yaml`` (the archive root or its single top
    folder). Raises :class:`SessionError` (nothing left behind) on any unsafe entry.
    """
    where = Path(label)
    if len(data) > max_upload_bytes:
        raise SessionError(where, f"upload is {len(data) / 1e6:.1f} MB; the limit is {max_upload_bytes / 1e6:.0f} MB")
    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
    except zipfile.BadZipFile:
        raise SessionError(where, "not a zip archive (zip the session folder and upload the .zip)") from None
    infos = zf.infolist()
    if len(infos) > max_files:
        raise SessionError(where, f"archive holds {len(infos)} entries; the limit is {max_files}")
    plan = []
    for info in infos:
        rel = _safe_member_path(info.filename, where)
        kind = stat.S_IFMT(info.external_attr >> 16)  # 0: no Unix type recorded (plain file)
        if kind not in (0, stat.S_IFREG, stat.S_IFDIR):
            raise SessionError(where, f"archive entry '{info.filename}' is a symlink or special file")
        if info.flag_bits & 0x1:
            raise SessionError(where, f"archive entry '{info.filename}' is encrypted")
        plan.append((info, rel))
    dest_parent = Path(dest_parent)
    dest_parent.mkdir(parents=True, exist_ok=True)
    out = Path(tempfile.mkdtemp(prefix="session-", dir=dest_parent)).resolve()
    try:
        total = 0
        for info, rel in plan:
            target = (out / Path(*rel.parts)).resolve() if rel.parts else out
            if target != out and out not in target.parents:
                raise SessionError(where, f"archive entry '{info.filename}' leaves the session folder")
            if info.is_dir():
                target.mkdir(parents=True, exist_ok=True)
                continue
            target.parent.mkdir(parents=True, exist_ok=True)
            with zf.open(info) as src, open(target, "xb") as dst:
                while True:
                    chunk = src.read(1 << 20)
                    if not chunk:
                        break
                    total += len(chunk)
                    if total > max_unpacked_bytes:
                        raise SessionError(where, f"archive unpacks to more than {max_unpacked_bytes / 1e6:.0f} MB")
                    dst.write(chunk)
        return _find_session_root(out, where)
    except BaseException:
        shutil.rmtree(out, ignore_errors=True)
        raise
    finally:
        zf.close()


def _find_session_root(out: Path, where: Path) -> Path:
    if (out / "session.yaml").is_file():
        return out
    subs = [p for p in out.iterdir() if p.is_dir() and not p.name.startswith(("__MACOSX", "."))]
    if len(subs) == 1 and (subs[0] / "session.yaml").is_file():
        return subs[0]
    raise SessionError(where, "archive holds no session.yaml at its top level or in a single top folder")
