"""Fingerprint of the synthetic sessions every preset writes (small variants), to check that a
refactor of the generator leaves its output byte-identical.

Run: .venv/bin/python benchmarks/synth_hashes.py [--presets quick,moved] [--seed 3] [--out hashes.tsv]
Prints a table: preset, files, bytes, SHA-256 of the tree (relative paths and contents).
Compare two runs (before / after a change) with ``--compare before.tsv``.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._table import print_table  # noqa: E402
from calib_core.synth.generate import generate_session  # noqa: E402
from calib_core.synth.presets import PRESETS  # noqa: E402

SMALL = {"scale": 0.15, "pan_step_deg": 3.0, "n_captures": 4}  # every code path, a few seconds per preset


def tree_digest(root: Path) -> tuple[int, int, str]:
    """(files, bytes, sha256) over the sorted relative paths and contents under ``root``."""
    h, n, size = hashlib.sha256(), 0, 0
    for p in sorted(q for q in root.rglob("*") if q.is_file()):
        data = p.read_bytes()
        h.update(p.relative_to(root).as_posix().encode() + b"\0" + data)
        n, size = n + 1, size + len(data)
    return n, size, h.hexdigest()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", default=",".join(PRESETS))
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--out", help="write the table as TSV here too")
    ap.add_argument("--compare", help="a TSV from an earlier run: say per preset whether the digest is the same")
    a = ap.parse_args(argv)
    before = {}
    if a.compare:
        before = {r[0]: r[3] for r in (line.split("\t") for line in Path(a.compare).read_text().splitlines()[1:])}
    rows = []
    for name in a.presets.split(","):
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            root = generate_session(Path(tmp) / "s", name, a.seed, **SMALL)
            n, size, digest = tree_digest(root)
        row = [name, str(n), str(size), digest[:16], f"{time.perf_counter() - t0:.1f}"]
        if a.compare:
            row.append("same" if before.get(name) == digest[:16] else "DIFFERENT")
        rows.append(row)
    header = ["preset", "files", "bytes", "sha256 (16)", "s"] + (["vs before"] if a.compare else [])
    print_table(header, rows)
    if a.out:
        Path(a.out).write_text("\n".join("\t".join(r) for r in [header] + rows) + "\n")
    return 1 if any(r[-1] == "DIFFERENT" for r in rows) and a.compare else 0


if __name__ == "__main__":
    sys.exit(main())
