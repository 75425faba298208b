"""The one YAML reader for every file the tool reads (session.yaml, intrinsics, detections ...).

Safe against hostile files: the size is capped before reading; libyaml's event stream
(iterative, in C) is walked first to cap the nesting depth (libyaml's composer recurses
on the C stack and crashes at ~50k levels), the number of values (parsing costs about
1-2 us a value: the cap bounds the time) and the aliases; only then does libyaml compose
the document, and the size of the tree once aliases are expanded (a "billion laughs"
document) is checked before anything is constructed. Every violation is a
:class:`SessionError` naming the file. The returned data holds no shared sub-trees:
aliases are expanded into copies (bounded by the expansion cap), so a later save
writes exactly what was read and never walks a shared tree.
"""

from __future__ import annotations

from pathlib import Path

import yaml
from yaml.composer import Composer
from yaml.constructor import SafeConstructor
from yaml.nodes import MappingNode, SequenceNode
from yaml.resolver import Resolver

from calib_core.errors import SessionError

MAX_YAML_BYTES = 20_000_000
MAX_DEPTH = 64
MAX_ALIASES = 100_000  # our own saves never write aliases; other tools may
MAX_EXPANDED_NODES = 1_000_000  # only documents with aliases are expanded (others are trees already)
MAX_NODES = 500_000  # values in the file itself; a detections.yaml of 100 captures holds ~25 000

try:  # libyaml: its event parser is iterative; its composer recurses, so it runs only after prescan()
    from yaml._yaml import CParser as _Parser

    _C_LOADER = yaml.CSafeLoader

    def _init_parser(self, text):
        _Parser.__init__(self, text)
except (ImportError, AttributeError):  # pragma: no cover - pure-Python fallback
    _C_LOADER = None

    from yaml.parser import Parser as _PyParser
    from yaml.reader import Reader
    from yaml.scanner import Scanner

    class _Parser(Reader, Scanner, _PyParser):  # type: ignore[no-redef]
        pass

    def _init_parser(self, text):
        Reader.__init__(self, text)
        Scanner.__init__(self)
        _PyParser.__init__(self)


class YamlLimit(Exception):
    """A document went over one of the caps (message says which)."""


class _LimitedLoader(_Parser, Composer, SafeConstructor, Resolver):
    """Event parser + depth/alias-checked Python composer + safe constructor."""

    def __init__(self, text: str):
        _init_parser(self, text)
        Composer.__init__(self)
        SafeConstructor.__init__(self)
        Resolver.__init__(self)
        self._depth = 0
        self.aliases = 0
        self._open_anchors: list[str] = []

    # the parser classes define their own node API; use the Python composer's
    check_node = Composer.check_node
    get_node = Composer.get_node
    get_single_node = Composer.get_single_node

    def compose_node(self, parent, index):
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent):
            self.aliases += 1
            if self.aliases > MAX_ALIASES:
                raise YamlLimit(f"more than {MAX_ALIASES} aliases")
            if event.anchor in self._open_anchors:
                raise YamlLimit(f"alias *{str(event.anchor)[:40]} refers to a node that contains it")
        anchor = getattr(event, "anchor", None) if not isinstance(event, yaml.AliasEvent) else None
        self._nodes = getattr(self, "_nodes", 0) + 1
        if self._nodes > MAX_NODES:
            raise YamlLimit(f"more than {MAX_NODES} values")
        self._depth += 1
        if self._depth > MAX_DEPTH:
            raise YamlLimit(f"nested more than {MAX_DEPTH} levels deep")
        if anchor is not None:
            self._open_anchors.append(anchor)
        try:
            return Composer.compose_node(self, parent, index)
        finally:
            self._depth -= 1
            if anchor is not None:
                self._open_anchors.pop()


def expanded_size(node, cap: int = MAX_EXPANDED_NODES) -> int:
    """Number of nodes once every alias is expanded; raises YamlLimit above ``cap``."""
    memo: dict[int, int] = {}
    order, stack, seen = [], [node], set()
    while stack:  # iterative post-order over the (acyclic: YAML aliases point backwards) graph
        n = stack.pop()
        if id(n) in seen:
            continue
        seen.add(id(n))
        order.append(n)
        stack.extend(_children(n))
    for n in reversed(order):
        total = 1 + sum(memo.get(id(c), 1) for c in _children(n))
        if total > cap:
            raise YamlLimit(f"expands to more than {cap} values (an alias bomb?)")
        memo[id(n)] = total
    return memo[id(node)]


def _children(n):
    if isinstance(n, SequenceNode):
        return n.value
    if isinstance(n, MappingNode):
        return [x for kv in n.value for x in kv]
    return []


def _unshare(x):
    """Copy shared lists and dicts (from aliases) so the result is a tree (depth is capped)."""
    if isinstance(x, dict):
        return {k: _unshare(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_unshare(v) for v in x]
    return x


def _parse_with_libyaml(text: str):
    """Fast path: the checks on the event stream first, then libyaml's composer (now safe)."""
    aliases = prescan(text)
    loader = _C_LOADER(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        if not aliases:
            return loader.construct_document(node)
        expanded_size(node)
        return _unshare(loader.construct_document(node))
    finally:
        loader.dispose()


def prescan(text: str) -> int:
    """Walk libyaml's event stream (iterative, in C) checking depth and aliases; return the
    alias count. Only a document that passes is handed to libyaml's (recursive) composer."""
    parser = _Parser(text)
    depth, aliases, open_anchors, nodes = 0, 0, [], 0
    try:
        while True:
            ev = parser.get_event()
            if isinstance(ev, yaml.NodeEvent):
                nodes += 1
                if nodes > MAX_NODES:
                    raise YamlLimit(f"more than {MAX_NODES} values")
            if isinstance(ev, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
                depth += 1
                if depth > MAX_DEPTH:
                    raise YamlLimit(f"nested more than {MAX_DEPTH} levels deep")
                open_anchors.append(ev.anchor)
            elif isinstance(ev, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
                depth -= 1
                open_anchors.pop()
            elif isinstance(ev, yaml.AliasEvent):
                aliases += 1
                if aliases > MAX_ALIASES:
                    raise YamlLimit(f"more than {MAX_ALIASES} aliases")
                if ev.anchor in open_anchors:
                    raise YamlLimit(f"alias *{str(ev.anchor)[:40]} refers to a node that contains it")
            elif isinstance(ev, yaml.StreamEndEvent):
                return aliases
    finally:
        parser.dispose()


def parse_yaml_text(text: str):
    """Parse one YAML document with the caps; raises yaml.YAMLError or YamlLimit."""
    if _C_LOADER is not None:
        return _parse_with_libyaml(text)
    loader = _LimitedLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        if not loader.aliases:
            return loader.construct_document(node)
        expanded_size(node)
        return _unshare(loader.construct_document(node))
    finally:
        loader.dispose()


def read_yaml(path: Path, what: str = "file", max_bytes: int = MAX_YAML_BYTES):
    """Read a YAML file with every cap; each problem is one SessionError naming ``path``."""
    path = Path(path)
    try:
        if not path.is_file():
            raise SessionError(path, f"{what} not found" if not path.exists() else f"{what} is not a regular file")
        size = path.stat().st_size
        if size > max_bytes:
            raise SessionError(path, f"{what} is {size / 1e6:.1f} MB: more than the {max_bytes / 1e6:.0f} MB "
                                     "a YAML file may have here")
        with open(path, "rb") as f:
            raw = f.read(max_bytes + 1)
    except OSError as e:
        raise SessionError(path, f"cannot read {what}: {e.strerror or type(e).__name__}") from None
    if len(raw) > max_bytes:  # grew while we looked
        raise SessionError(path, f"{what} is more than the {max_bytes / 1e6:.0f} MB a YAML file may have here")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise SessionError(path, "not a text file (invalid UTF-8)") from None
    return parse_yaml_checked(path, text)


def parse_yaml_checked(path: Path, text: str):
    """:func:`parse_yaml_text` with every failure turned into one SessionError naming ``path``."""
    try:
        return parse_yaml_text(text)
    except YamlLimit as e:
        raise SessionError(path, f"invalid YAML (refused): {e}") from None
    except yaml.YAMLError as e:
        raise SessionError(path, f"invalid YAML{yaml_where(e)}") from None
    except (RecursionError, MemoryError):
        raise SessionError(path, "invalid YAML (refused): too deeply nested or too large") from None
    except (TypeError, ValueError, OverflowError) as e:  # e.g. an unhashable key, a bad timestamp
        raise SessionError(path, f"invalid YAML: {type(e).__name__}") from None


def yaml_where(e: yaml.YAMLError) -> str:
    """' at line L, column C: problem' text of a YAML error (no document text echoed)."""
    mark = getattr(e, "problem_mark", None)
    what = getattr(e, "problem", None) or getattr(e, "context", None) or type(e).__name__
    what = str(what)[:120]
    return f" at line {mark.line + 1}, column {mark.column + 1}: {what}" if mark else f": {what}"


def read_yaml_mapping(path: Path, what: str = "file") -> dict:
    """Read a YAML file that must hold a mapping at the top level."""
    data = read_yaml(path, what)
    if not isinstance(data, dict):
        raise SessionError(path, f"expected a YAML mapping at the top level, got {type(data).__name__}")
    return data
