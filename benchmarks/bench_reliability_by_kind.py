"""Before / after reliability of the image detection score, per kind, from two listings (issue 11).

Each input is the ``--list`` output of ``bench_image_presets.py`` (with ``--negatives`` for the
ball-free images; several kinds' outputs may be concatenated), one of the old code and one of the
new (run the old code from an export: ``git archive main | tar -x -C DIR`` and
``PYTHONPATH=DIR``). Images are matched by kind, seed, ball / no ball and background use.
Printed: per kind, the reliability table (score bins: detections, mean score, share right)
before and after on the images both listings hold; the targets (top bin right >= 97 %, no
ball-free find >= 0.9); and every image whose outcome changed (found, right, score moved by
more than 0.05), so that what got worse is seen image by image.

Run: .venv/bin/python benchmarks/bench_reliability_by_kind.py BEFORE.txt AFTER.txt [--kinds tank,dim]
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _table import print_table, print_targets  # noqa: E402

from calib_core.detect.image.score import reliability_rows  # noqa: E402

TOL_PX = 3.0
TOP_BIN = 0.95
NEGATIVE_MAX = 0.9
LINE = re.compile(r"^(?P<label>\S+)(?P<neg> no ball)?\s+bg=(?P<bg>True|False)\s+(?:r=\s*\S+\s+)?found=(?P<found>True|False)\s+"
                  r"(?:err=\s*(?P<err>\S+)\s+)?score=(?P<score>\S+)\s?(?P<reason>.*)$")


def parse(path: Path) -> dict:
    """(kind, seed, has ball, bg) -> (found, right, score, reason) of a ``--list`` output."""
    out = {}
    for line in path.read_text().splitlines():
        m = LINE.match(line)
        if not m:
            continue
        label = m["label"]
        seed = re.search(r"/s(\d+)$", label)
        if seed is None:
            continue
        found = m["found"] == "True"
        ball = m["neg"] is None
        right = found and ball and m["err"] not in (None, "-") and float(m["err"]) <= TOL_PX
        out[(label.split("/")[0], int(seed.group(1)), ball, m["bg"] == "True")] = (found, right, float(m["score"]),
                                                                                   m["reason"].strip())
    return out


def _scored(rows: dict, keys) -> list:
    return [(rows[k][2], rows[k][1]) for k in keys if rows[k][0]]


def _bins(scored) -> dict:
    return {(lo, hi): (n, mean, right) for lo, hi, n, mean, right in reliability_rows(scored)} if scored else {}


def kind_table(kind: str, before: dict, after: dict, keys) -> list:
    """Rows (bin, before n / mean / right, after n / mean / right) for one kind."""
    b, a = _bins(_scored(before, keys)), _bins(_scored(after, keys))
    rows = []
    for lo, hi in sorted(set(b) | set(a)):
        cell = lambda d: "-" if (lo, hi) not in d else f"{d[(lo, hi)][0]} / {d[(lo, hi)][1]:.3f} / {d[(lo, hi)][2]:.3f}"  # noqa: E731
        rows.append([kind, f"[{lo:.2f}, {hi:.2f}{')' if hi < 1 else ']'}", cell(b), cell(a)])
    return rows


def targets(kind: str, rows: dict, keys, when: str) -> list:
    top = [r for s, r in _scored(rows, keys) if s >= TOP_BIN]
    neg = [rows[k][2] for k in keys if not k[2] and rows[k][0]]
    share = sum(top) / len(top) if top else float("nan")
    return [(f"{kind} {when}: top bin right >= 97 %", f"{sum(top)} of {len(top)}", not top or share >= 0.97),
            (f"{kind} {when}: no ball-free find >= {NEGATIVE_MAX}", f"max {max(neg, default=0.0):.2f}",
             max(neg, default=0.0) < NEGATIVE_MAX)]


def changed(before: dict, after: dict, keys) -> list:
    rows = []
    for k in sorted(keys):
        b, a = before[k], after[k]
        if b[:2] != a[:2] or abs(b[2] - a[2]) > 0.05:
            what = "better" if (a[1] > b[1] or (not k[2] and b[0] and (not a[0] or a[2] < b[2]))) else \
                "worse" if (a[1] < b[1] or (not k[2] and a[2] > b[2])) else "changed"
            fmt = lambda x: f"{'right' if x[1] else 'found' if x[0] else 'none'} {x[2]:.2f} {x[3][:60]}"  # noqa: E731
            rows.append([f"{k[0]} s{k[1]} {'ball' if k[2] else 'no ball'}{' bg' if k[3] else ''}", fmt(b), fmt(a), what])
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    ap.add_argument("--kinds", default=None, help="comma-separated kinds (default: every kind in both)")
    a = ap.parse_args(argv)
    before, after = parse(a.before), parse(a.after)
    common = set(before) & set(after)
    kinds = a.kinds.split(",") if a.kinds else sorted({k[0] for k in common})
    rows, checks = [], []
    for kind in kinds:
        keys = [k for k in common if k[0] == kind]
        rows += kind_table(kind, before, after, keys)
        checks += targets(kind, before, keys, "before") + targets(kind, after, keys, "after")
    print_table(["kind", "score bin", "before: n / mean score / right", "after: n / mean score / right"], rows,
                title=f"Reliability per kind ({len(common)} images in both listings)")
    print_targets(checks)
    diff = changed(before, after, [k for k in common if k[0] in kinds])
    print()
    print_table(["image", "before", "after", ""], diff or [["-", "-", "-", "no image changed"]],
                title="Images whose outcome changed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
