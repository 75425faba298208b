"""Entry point: ``sonarcal COMMAND ...``.

Every command module exposes ``add_parser(subparsers)`` which registers its parser
with ``set_defaults(run=function)``; ``run(args) -> int`` returns the exit status.
User-fixable problems (:class:`SessionError`) become one line on stderr and exit 2.
"""

from __future__ import annotations

import argparse
import importlib
import keyword
import os
import sys
import traceback

from calib_core import __version__
from calib_core.errors import SessionError, one_line

COMMANDS = ["info", "synth", "detect", "calibrate", "intrinsics", "stereo", "serve", "export", "report", "import", "plan"]


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The parser of every command, or with ``only`` of that one (start-up: the other commands'
    modules and what they import are not loaded)."""
    p = argparse.ArgumentParser(prog="sonarcal", description="Camera to 3D imaging sonar calibration.")
    p.add_argument("--version", action="version", version=f"sonarcal {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for name in [only] if only in COMMANDS else COMMANDS:
        importlib.import_module(command_module(name)).add_parser(sub)
    return p


def command_module(name: str) -> str:
    """The module of command ``name`` (a keyword such as ``import`` gets PEP 8's trailing underscore)."""
    return f"sonarcal_cli.commands.{name}_" if keyword.iskeyword(name) else f"sonarcal_cli.commands.{name}"


def _quiet_native_logs() -> None:
    """OpenCV logs decoder warnings ("PNG input buffer is incomplete") straight to stderr, and its
    FFmpeg backend its own errors ("moov atom not found" for a broken video, read from the variable
    at the first VideoCapture); our SessionError already says what is wrong, in one line naming the file."""
    if not os.environ.get("SONARCAL_DEBUG"):
        os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET
    try:
        import cv2

        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR if os.environ.get("SONARCAL_DEBUG")
                                      else cv2.utils.logging.LOG_LEVEL_SILENT)
    except (ImportError, AttributeError):
        pass


def main(argv: list[str] | None = None) -> int:
    _quiet_native_logs()
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(argv[0] if argv else None)
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # argparse already printed a usage message
        return int(e.code or 0) if e.code in (0, None) else 2
    if not getattr(args, "run", None):
        parser.print_help()
        return 2
    try:
        return int(args.run(args) or 0)
    except SessionError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except OSError as e:  # permission denied, disk full, read-only folder: the user can fix these
        where = e.filename if e.filename is not None else "file system"
        print(one_line(f"error: {where}: {e.strerror or e}"), file=sys.stderr)
        return 2
    except MemoryError:
        print("error: out of memory (the input is too large for this machine)", file=sys.stderr)
        return 2
    except Exception as e:  # a bug: say so in one line; full trace only on request
        if os.environ.get("SONARCAL_DEBUG"):
            traceback.print_exc()
        print(one_line(f"internal error: {type(e).__name__}: {e} (set SONARCAL_DEBUG=1 for details; please report)"),
              file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
