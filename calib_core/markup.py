"""Escaping file- and user-derived text for Markdown/HTML, and ROS frame ids.

(Interim version in the workbench branch; the "security" branch owns this module.)
"""

from __future__ import annotations

import html
import re

_MD_SPECIAL = re.compile(r"([\\`*_{}\[\]()#+\-.!|<>~])")


def escape_html(text) -> str:
    return html.escape(str(text), quote=True)


def escape_md(text) -> str:
    """Text shown literally inside Markdown (which viser renders with raw HTML)."""
    return _MD_SPECIAL.sub(r"\\\1", html.escape(str(text), quote=False))


def ros_frame_id(name) -> str:
    """A valid ROS frame id from a name: letters, digits and underscores, not starting with a digit."""
    s = re.sub(r"[^A-Za-z0-9_]", "_", str(name))
    return s if s and not s[0].isdigit() else f"f_{s}"
