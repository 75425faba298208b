"""Terminal output helpers (rich): tables and a progress bar driven by core callbacks."""

from __future__ import annotations

import contextlib
import sys

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table
from rich.text import Text

# piped output: wide enough that report tables do not wrap
console = Console(highlight=False, width=None if sys.stdout.isatty() else 160)
err_console = Console(stderr=True, highlight=False, soft_wrap=True)


@contextlib.contextmanager
def progress_bar(description: str):
    """Yield a callback ``cb(done, total, label="")`` that drives a terminal progress bar.

    The bar is drawn on stderr only when it is a terminal, so piped output stays clean.
    """
    prog = Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TextColumn("{task.fields[label]}"), TimeElapsedColumn(),
                    console=err_console, transient=False, disable=not sys.stderr.isatty())
    with prog:
        task = prog.add_task(description, total=None, label="")

        def cb(done: int, total: int, label: str = "") -> None:
            prog.update(task, completed=done, total=total, label=label)

        yield cb


def table(title: str, columns: list[str], rows: list[list]) -> Table:
    """A rich table; every title and cell is plain text (names from files are never rich markup)."""
    t = Table(title=Text(title), title_justify="left")
    for c in columns:
        t.add_column(Text(str(c)))
    for r in rows:
        t.add_row(*[Text(str(v)) for v in r])
    return t
