"""The one exception type for problems a user can fix (bad files, bad values).

Shells (CLI, workbench) turn it into a single message and exit status 2;
they never show a traceback for it.
"""

from __future__ import annotations

from pathlib import Path


class SessionError(Exception):
    """A problem with a user's file or input, with the file named.

    Attributes:
        path: the file or folder the problem is in (may be None for pure values).
        problem: a short sentence saying what is wrong and, where possible, how to fix it.
    """

    def __init__(self, path: str | Path | None, problem: str):
        self.path = None if path is None else Path(path)
        self.problem = problem
        super().__init__(one_line(f"{self.path}: {problem}" if self.path is not None else problem))


def one_line(text) -> str:
    """``text`` as one line a terminal shows as it is: every control or format character (newline,
    ESC, bidi override, zero-width) written as its escape (``\\n``, ``\\x1b``, ``\\u202e``).

    File names are chosen by whoever made the files: a name holding a newline or an escape
    sequence would otherwise forge a second message line or recolour, retitle or hyperlink the
    user's terminal when the name is shown in a message."""
    text = text if isinstance(text, str) else str(text)
    if text.isprintable():
        return text
    return "".join(ch if ch.isprintable() or ch == " " else repr(ch)[1:-1] for ch in text)


class Cancelled(Exception):
    """Raised by a progress callback to stop long work (the workbench shutting down).

    Long loops call their progress callback between steps; a shell that wants the work to stop
    raises this from the callback, and the work ends at the next step, leaving nothing written."""


def short_repr(value, n: int = 60) -> str:
    """repr of a value read from a user's file, cut to ``n`` characters for messages."""
    r = repr(value)
    return r if len(r) <= n else r[: n - 3] + "..."
