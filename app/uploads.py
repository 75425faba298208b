"""Safe unpacking of a zipped session uploaded from the browser (pure Python).

Refuses absolute paths, drive letters, ``..`` escapes, symlinks and other special
entries, more than ``max_files`` members and more than ``max_unpacked_bytes`` once
unpacked (zip bombs), checking the bytes actually written, not the sizes the archive
claims. Nothing inside an upload is ever executed.
"""

from __future__ import annotations

import io
import logging
import os
import shutil
import stat
import tempfile
import zipfile
import zlib
from pathlib import Path, PurePosixPath

from calib_core.errors import SessionError, short_repr
from calib_core.session import has_control

log = logging.getLogger("sonarcal.app")

MAX_UPLOAD_BYTES = 200 * 1000 * 1000  # decimal MB, so the button and the refusal say the same number
MAX_UNPACKED_BYTES = 1000 * 1000 * 1000
MAX_FILES = 20000
UPLOAD_PREFIX = "session-"
INCOMING_PREFIX = "incoming-"


def mb_text(n_bytes: int) -> str:
    """'200 MB' (decimal megabytes): the one way sizes of uploads are shown."""
    return f"{n_bytes / 1e6:.0f} MB" if n_bytes >= 1e7 else f"{n_bytes / 1e6:.1f} MB"


def upload_limit_text(max_bytes: int = MAX_UPLOAD_BYTES) -> str:
    """The limit as the button label and the refusal both show it."""
    return f"max {mb_text(max_bytes)}"


def oversize_problem(size: int, max_bytes: int = MAX_UPLOAD_BYTES) -> str:
    return f"upload is {mb_text(size)}; the limit is {mb_text(max_bytes)}"


MAX_MEMBER_NAME = 1024  # characters of a whole entry name; each folder or file name at most NAME_MAX bytes
NAME_MAX = 255


def _safe_member_path(name: str, where: Path) -> PurePosixPath:
    if "\x00" in name:
        raise SessionError(where, "archive entry name holds a NUL character")
    if has_control(name):  # a newline or escape would reach file names, messages and the page
        raise SessionError(where, f"archive entry {short_repr(name)} has control characters in its name")
    if len(name) > MAX_MEMBER_NAME or any(len(part.encode()) > NAME_MAX for part in name.replace("\\", "/").split("/")):
        raise SessionError(where, f"archive entry {short_repr(name)} has a name longer than file systems allow")
    norm = name.replace("\\", "/")
    if norm.startswith("/") or (len(norm) > 1 and norm[1] == ":"):
        raise SessionError(where, f"archive entry '{name}' has an absolute path")
    p = PurePosixPath(norm)
    if any(part == ".." for part in p.parts):
        raise SessionError(where, f"archive entry '{name}' leaves the session folder ('..')")
    return p


def safe_unpack_zip(data, dest_parent: Path, label: str = "upload.zip",
                    max_upload_bytes: int = MAX_UPLOAD_BYTES,
                    max_unpacked_bytes: int = MAX_UNPACKED_BYTES,
                    max_files: int = MAX_FILES) -> Path:
    """Unpack a zipped session (bytes, or the path of a file) into a new folder under ``dest_parent``.

    Returns the folder holding ``session.yaml`` (the archive root or its single top
    folder). Raises :class:`SessionError` (nothing left behind) on any unsafe entry.
    """
    where = Path(label)
    size = len(data) if isinstance(data, (bytes, bytearray)) else os.path.getsize(data)
    if size > max_upload_bytes:
        raise SessionError(where, oversize_problem(size, max_upload_bytes))
    try:
        zf = zipfile.ZipFile(io.BytesIO(data) if isinstance(data, (bytes, bytearray)) else data)
    except (zipfile.BadZipFile, OSError, ValueError, EOFError):
        raise SessionError(where, "not a zip archive (zip the session folder and upload the .zip)") from None
    with zf:
        plan = _plan(zf, where, max_files)
        dest_parent = Path(dest_parent)
        dest_parent.mkdir(parents=True, exist_ok=True)
        out = Path(tempfile.mkdtemp(prefix=UPLOAD_PREFIX, dir=dest_parent)).resolve()
        try:
            _extract(zf, plan, out, where, max_unpacked_bytes)
            return _find_session_root(out, where)
        except (FileExistsError, NotADirectoryError, IsADirectoryError):
            shutil.rmtree(out, ignore_errors=True)
            raise SessionError(where, "archive holds the same path twice, or a file where a folder should be") from None
        # zipfile raises NotImplementedError for a compression method it cannot read (not a stub here)
        except (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, NotImplementedError, ValueError, zlib.error) as e:
            shutil.rmtree(out, ignore_errors=True)
            raise SessionError(where, f"corrupt or unsupported zip archive ({type(e).__name__})") from None
        except BaseException:
            shutil.rmtree(out, ignore_errors=True)
            raise


def _plan(zf: zipfile.ZipFile, where: Path, max_files: int) -> list:
    """(entry, safe relative path) of every member; refuses symlinks, special files, encryption."""
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
    return plan


def _extract(zf: zipfile.ZipFile, plan: list, out: Path, where: Path, max_unpacked_bytes: int) -> None:
    """Write the planned entries under ``out``, counting the bytes actually written (zip bombs)."""
    total = 0
    too_big = f"archive unpacks to more than {mb_text(max_unpacked_bytes)}"
    for info, rel in plan:
        target = (out / Path(*rel.parts)).resolve() if rel.parts else out
        if target != out and out not in target.parents:
            raise SessionError(where, f"archive entry '{info.filename}' leaves the session folder")
        if info.is_dir():
            target.mkdir(parents=True, exist_ok=True)
            continue
        target.parent.mkdir(parents=True, exist_ok=True)
        if info.file_size > max_unpacked_bytes - total:
            raise SessionError(where, too_big)
        with zf.open(info) as src, open(target, "xb") as dst:
            while chunk := src.read(1 << 20):
                total += len(chunk)
                if total > max_unpacked_bytes:
                    raise SessionError(where, too_big)
                dst.write(chunk)


def _find_session_root(out: Path, where: Path) -> Path:
    if (out / "session.yaml").is_file():
        return out
    subs = [p for p in out.iterdir() if p.is_dir() and not p.name.startswith(("__MACOSX", "."))]
    if len(subs) == 1 and (subs[0] / "session.yaml").is_file():
        return subs[0]
    raise SessionError(where, "archive holds no session.yaml at its top level or in a single top folder")


# ---- the uploads folder -------------------------------------------------------------
class UploadStore:
    """The folder uploads are streamed to and unpacked in.

    Only the session open now is kept (:meth:`keep_only`); :meth:`cleanup` (server stop,
    SIGTERM, SIGINT) removes everything this store put there, and the folder itself when
    the store made it.
    """

    def __init__(self, root=None):
        self.owned = root is None
        self.root = Path(tempfile.mkdtemp(prefix="sonarcal-uploads-")) if root is None else Path(root)
        self.root.mkdir(parents=True, exist_ok=True)
        self.root = self.root.resolve()

    def incoming_file(self) -> Path:
        fd, name = tempfile.mkstemp(prefix=INCOMING_PREFIX, suffix=".zip", dir=self.root)
        os.close(fd)
        return Path(name)

    def keep_only(self, session_root) -> None:
        """Delete every unpacked upload except the one holding ``session_root``."""
        keep = Path(session_root).resolve() if session_root is not None else None
        for entry in self._entries(UPLOAD_PREFIX):
            if keep is not None and (keep == entry or entry in keep.parents):
                continue
            shutil.rmtree(entry, ignore_errors=True)

    def _entries(self, prefix: str) -> list[Path]:
        try:
            return [p for p in self.root.iterdir() if p.name.startswith(prefix)]
        except OSError:
            return []

    def cleanup(self) -> None:
        if self.owned:
            shutil.rmtree(self.root, ignore_errors=True)
            return
        for entry in self._entries(UPLOAD_PREFIX) + self._entries(INCOMING_PREFIX):
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                entry.unlink(missing_ok=True)


def release_session_lock(session_root) -> None:
    """Remove the session's ``.detections.yaml.lock`` unless another process holds it."""
    if session_root is None:
        return
    path = Path(session_root) / ".detections.yaml.lock"
    try:
        import fcntl

        fd = os.open(path, os.O_RDWR | os.O_NOFOLLOW)
    except (ImportError, OSError):
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        path.unlink(missing_ok=True)
    except OSError:
        pass  # in use by another writer: theirs to keep
    finally:
        os.close(fd)


def port_taken_warning(asked: int, bound: int) -> str | None:
    """The warning shown when the asked-for port was taken and viser chose another."""
    if asked and bound != asked:
        return f"port {asked} is taken (another program or workbench uses it); using port {bound} instead"
    return None
