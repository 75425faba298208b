"""Markdown tables for the benchmarks' output (pasted into BENCHMARKS.md as they are)."""

from __future__ import annotations


def markdown_table(header: list, rows: list, align: bool = True) -> str:
    """A Markdown table of ``header`` and ``rows`` (cells turned into text with ``str``);
    with ``align`` the columns are padded to a common width so the text reads as a table too."""
    cells = [[str(v) for v in r] for r in [header, *rows]]
    widths = [max(len(r[i]) for r in cells if i < len(r)) for i in range(len(header))] if align else [0] * len(header)

    def line(r):
        return "| " + " | ".join(v.ljust(widths[i]) for i, v in enumerate(r)) + " |"

    rule = "|" + "|".join("-" * (w + 2) if align else "---" for w in widths) + "|"
    return "\n".join([line(cells[0]), rule, *map(line, cells[1:])])


def print_table(header: list, rows: list, title: str | None = None, align: bool = True) -> None:
    """Print :func:`markdown_table` (after a bold ``title`` and a blank line when given)."""
    if title:
        print(f"**{title}**\n")
    print(markdown_table(header, rows, align), flush=True)


def print_targets(checks: list, title: str = "Targets") -> None:
    """Print each ``(target, value, met)`` as ``[met] target: value`` (``[MISSED]`` when not met)."""
    print(f"\n{title}")
    for name, val, ok in checks:
        print(f"  [{'met' if ok else 'MISSED'}] {name}: {val}")
