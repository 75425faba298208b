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
        super().__init__(f"{self.path}: {problem}" if self.path is not None else problem)


class Cancelled(Exception):
    """Raised by a progress callback to stop long work (the workbench shutting down).

    Long loops call their progress callback between steps; a shell that wants the work to stop
    raises this from the callback, and the work ends at the next step, leaving nothing written."""


def short_repr(value, n: int = 60) -> str:
    """repr of a value read from a user's file, cut to ``n`` characters for messages."""
    r = repr(value)
    return r if len(r) <= n else r[: n - 3] + "..."
