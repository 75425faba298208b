"""Escaping of text that came from a file or a user before it reaches Markdown or HTML.

The workbench shows names (session, cameras, captures), reasons and error messages in
viser Markdown, which renders raw HTML; the report is HTML. Every such interpolation
goes through :func:`escape_md` or :func:`escape_html`. Letters, digits, spaces and
non-ASCII text ("Kamera ü 1") pass through unchanged; only markup is neutralised.
:func:`ros_frame_id` turns any name into a valid ROS frame id for exports.
"""

from __future__ import annotations

import html
import re
import unicodedata

# characters with a meaning in CommonMark / GFM (inline and at a line start)
_MD_SPECIAL = set("\\`*_{}[]()#+-.!|~>")
_HTML = {"&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#x27;"}


def _visible(text) -> str:
    """Text without control characters (newlines and tabs become spaces)."""
    text = text if isinstance(text, str) else str(text)
    out = []
    for ch in text:
        if ch in "\n\r\t\v\f":
            out.append(" ")
        elif unicodedata.category(ch) in ("Cc", "Cf") or ch in "\u2028\u2029":
            continue  # invisible controls, bidi overrides, zero-width characters
        else:
            out.append(ch)
    return "".join(out)


def escape_html(text) -> str:
    """Text for an HTML element or quoted attribute: ``& < > " '`` become entities."""
    return html.escape(_visible(text), quote=True)


def escape_md(text) -> str:
    """Text for viser Markdown: HTML entities for ``& < > " '`` and a backslash before
    every Markdown punctuation character, on one line. ``**{escape_md(name)}**`` shows
    exactly ``name`` in bold, whatever the name holds."""
    out = []
    for ch in _visible(text):
        if ch in _HTML:
            out.append(_HTML[ch])
        elif ch in _MD_SPECIAL:
            out.append("\\" + ch)
        else:
            out.append(ch)
    return "".join(out)


def escape_md_code(text) -> str:
    """Text for inside a Markdown code span (`` `...` ``) where backslashes are literal:
    backticks and HTML markup are replaced by look-alike entities."""
    return escape_html(text).replace("`", "&#x60;")


def plain_line(text) -> str:
    """One line of plain text (for comments in exported files): no newlines, no control characters."""
    return _visible(text)


_ROS_BAD = re.compile(r"[^A-Za-z0-9_]+")


def ros_frame_id(name) -> str:
    """A valid ROS frame id from any name: segments ``[A-Za-z_][A-Za-z0-9_]*`` joined by
    ``/`` (a tf prefix such as ``robot/sonar`` is kept; no leading ``/``).

    Accents are folded ("Kamera ü 1" -> "Kamera_u_1"), every other run of characters
    outside the set becomes one underscore, and a segment starting with a digit gets an
    ``f_`` prefix. Never empty.
    """
    text = unicodedata.normalize("NFKD", _visible(name))
    text = "".join(ch for ch in text if not unicodedata.combining(ch))
    segments = []
    for part in text.split("/"):
        part = _ROS_BAD.sub("_", part).strip("_")[:100]
        if part:
            segments.append("f_" + part if part[0].isdigit() else part)
    return "/".join(segments) or "frame"
