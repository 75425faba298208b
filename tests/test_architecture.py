"""The layering the team guide asks for, read from the source with ``ast`` (nothing imported).

- ``calib_core`` never imports the shells (``app``, ``sonarcal_cli``) nor ``viser``, not even
  inside a function.
- No import cycles among ``calib_core``'s modules, counting imports made inside functions too
  (a lazy import hides a cycle from Python, not from the reader).
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FORBIDDEN = ("app", "sonarcal_cli", "viser")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imported_names(path: Path, module: str | None = None, known: set[str] | None = None) -> list[str]:
    """The modules the imports in ``path`` (module ``module``) name, relative imports resolved.

    ``from pkg import x`` names ``pkg.x`` when that is one of the ``known`` modules, else ``pkg``;
    without ``known`` it names both.
    """
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    module = module or module_name(path)
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    names = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            subs = [f"{base}.{a.name}" for a in node.names]
            if known is None:
                names += [base] + subs
            else:
                names += [sub if sub in known else base for sub in subs]
    return names


def import_graph(package: str = "calib_core") -> dict[str, set[str]]:
    """Module -> the modules of ``package`` it imports (``from pkg import mod`` counts as ``mod`` only)."""
    files = {module_name(p): p for p in (ROOT / package).rglob("*.py")}
    graph = {}
    for mod, path in files.items():
        targets = set()
        for name in imported_names(path, mod, set(files)):
            if name in files and name != mod:
                targets.add(name)
        graph[mod] = targets
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle (its modules in order, the first repeated at the end), or None."""
    state: dict[str, int] = {}  # 1 on the current path, 2 done
    for start in sorted(graph):
        if state.get(start):
            continue
        path, stack = [start], [iter(sorted(graph[start]))]
        state[start] = 1
        while stack:
            nxt = next(stack[-1], None)
            if nxt is None:
                state[path.pop()] = 2
                stack.pop()
            elif state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            elif not state.get(nxt):
                state[nxt] = 1
                path.append(nxt)
                stack.append(iter(sorted(graph[nxt])))
    return None


def test_find_cycle_finds_a_cycle_and_only_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set(), "d": {"d2"}, "d2": {"d"}}) == ["d", "d2", "d"]


def test_relative_imports_are_resolved(tmp_path):
    f = tmp_path / "m.py"
    f.write_text("from . import x\nfrom ..y import z\ndef g():\n    import app.state\n")
    names = imported_names(f, "calib_core.solve.m")
    assert {"calib_core.solve.x", "calib_core.y.z", "app.state"} <= set(names)
    known = {"calib_core.solve.x", "calib_core.y"}
    assert imported_names(f, "calib_core.solve.m", known) == ["calib_core.solve.x", "calib_core.y", "app.state"]


def test_calib_core_imports_no_shell_and_no_viser():
    bad = []
    for path in sorted((ROOT / "calib_core").rglob("*.py")):
        for name in imported_names(path):
            if name.split(".")[0] in FORBIDDEN:
                bad.append(f"{path.relative_to(ROOT)} imports {name}")
    assert not bad, "\n".join(bad)


def test_calib_core_has_no_import_cycle():
    graph = import_graph()
    assert len(graph) > 50 and any(graph.values())  # the scan saw the package and its imports
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)
