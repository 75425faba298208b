"""Docstring cross-references (``:mod:`.fit```, ``:func:`calib_core.x.y```) name modules and
names that exist: after a package move (detect/image_fit.py -> detect/image/fit.py) a stale
reference sends a reader to a file that is gone. Read with ``ast`` and the file tree only."""

from __future__ import annotations

import ast
import re
from functools import lru_cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ROLE = re.compile(r":(?:mod|func|class|data|meth|attr|exc):`~?([.A-Za-z0-9_]+)`")


def _module_path(dotted: str) -> Path | None:
    p = ROOT.joinpath(*dotted.split("."))
    if p.with_suffix(".py").is_file():
        return p.with_suffix(".py")
    if (p / "__init__.py").is_file():
        return p / "__init__.py"
    return None


@lru_cache(maxsize=None)
def _top_names(path: Path) -> frozenset:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names |= {n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)}
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names |= {(a.asname or a.name).split(".")[0] for a in node.names}
    return frozenset(names)


def _resolves(dotted: str) -> bool:
    """The longest prefix of ``dotted`` that is a module, and the next part a name in it."""
    parts = dotted.split(".")
    for k in range(len(parts), 0, -1):
        path = _module_path(".".join(parts[:k]))
        if path is None:
            continue
        if k == len(parts):
            return True
        nxt = parts[k]
        return nxt in _top_names(path) or (path.name == "__init__.py" and _module_path(".".join(parts[:k + 1])) is not None)
    return False


def _absolute(ref: str, path: Path) -> str | None:
    """``ref`` as a dotted name from the repository root (None: not one of ours)."""
    if not ref.startswith("."):
        return ref if ref.split(".")[0] in ("calib_core", "app", "sonarcal_cli") else None
    level = len(ref) - len(ref.lstrip("."))
    package = list(path.relative_to(ROOT).parent.parts)
    base = package[:len(package) - (level - 1)] if level > 1 else package
    return ".".join(base + [ref.lstrip(".")])


def stale_refs(roots=("calib_core", "app", "sonarcal_cli")) -> list[str]:
    out = []
    for root in roots:
        for path in sorted((ROOT / root).rglob("*.py")):
            for m in ROLE.finditer(path.read_text(encoding="utf-8")):
                dotted = _absolute(m.group(1), path)
                if dotted is not None and not _resolves(dotted):
                    out.append(f"{path.relative_to(ROOT)}: {m.group(0)}")
    return out


def test_the_checker_tells_a_stale_reference_from_a_good_one():
    here = ROOT / "calib_core" / "detect" / "image" / "detect.py"
    assert _resolves(_absolute(".fit", here)) and _resolves(_absolute(".fit.refine_candidate", here))
    assert not _resolves(_absolute(".image_fit", here))
    assert not _resolves("calib_core.detect.image_cone.px_per_rad")
    assert _resolves("calib_core.detect.image.cone.px_per_rad")
    assert _resolves(_absolute("..sonar_sim", ROOT / "calib_core" / "synth" / "range" / "capture.py"))


def test_docstring_references_name_existing_modules():
    assert stale_refs() == []


def test_the_readme_lists_every_synth_preset():
    """The README's ``sonarcal synth`` row names each preset (a new one, "underwater", was missing)."""
    from calib_core.synth.presets import PRESETS

    row = next(line for line in (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
               if line.startswith("| `sonarcal synth"))
    assert [p for p in PRESETS if not re.search(rf"(?<![\w-]){re.escape(p)}(?![\w-])", row)] == []
