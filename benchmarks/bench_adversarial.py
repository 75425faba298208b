"""Adversarial inputs (issue 14): peak memory and CPU time of each refusal.

    .venv/bin/python benchmarks/bench_adversarial.py

Builds every CLI case of ``tests/test_adversarial.py`` (YAML bombs, deep nesting, lying
image / LAS / LAZ / PCD / PLY / .npy headers, symlinks out of the session ...) and runs
them one after the other in one child process (``tests/adversarial_launch.py``: 2 GiB
address-space limit, the peak-RSS mark reset before each case). "peak MB" is the child's
VmHWM during the case, interpreter and readers included (about 90-190 MB of it is
Python, numpy, OpenCV and open3d already imported); "CPU s" is the CPU time the case
used; "unchanged" says whether the session folder and its parent hashed the same after the
case (nothing written, created or half-written). Targets (issue 14): exit 2 with one line naming
the file, no terminal escape on stderr, peak < 500 MB, < 10 s, session unchanged.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from conftest import tree_hash  # noqa: E402
from test_adversarial import CASES, LAUNCHER, _child_env, _prepare  # noqa: E402


def file_kind(name: str) -> str:
    """The kind of file a case attacks, from the file it must name."""
    suffix = Path(name.rstrip("/")).suffix.lower().lstrip(".")
    return {"yaml": "YAML", "json": "JSON", "": "folder"}.get(suffix, suffix.upper() or name)


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp)
        prepared = [_prepare(name, case, base) for name, case in CASES.items()]
        (base / "cases.json").write_text(json.dumps([{k: p[k] for k in ("name", "argv", "cwd")} for p in prepared]))
        t0 = time.monotonic()
        r = subprocess.run([sys.executable, str(LAUNCHER), str(base / "cases.json"), str(base / "results.json")],
                           capture_output=True, text=True, env=_child_env(), cwd=base)
        wall = time.monotonic() - t0
        if r.returncode != 0:
            print(r.stderr[-2000:])
            return 1
        res = json.loads((base / "results.json").read_text())
        for p in prepared:
            res[p["name"]]["same"] = (tree_hash(p["root"]) == p["before_root"]
                                      and tree_hash(p["parent"]) == p["before_parent"])
    ok_all = True
    print("| file kind | attack | exit | one line naming the file | peak MB | CPU s | session unchanged | met |\n"
          "|---|---|---|---|---|---|---|---|")
    for name, case in CASES.items():
        v = res[name]
        lines = [ln for ln in v["err"].splitlines() if ln.strip() and not ln.endswith("problem(s):")]
        one = len(lines) == 1 and case.file in lines[0] and "Traceback" not in v["err"] and "\x1b" not in v["err"]
        met = v["rc"] == 2 and one and v["peak_kb"] < 500 * 1024 and v["cpu"] < 10 and v["same"]
        ok_all &= met
        print(f"| {file_kind(case.file)} | {name} | {v['rc']} | {'yes' if one else 'NO'} | {v['peak_kb'] / 1024:.0f} | "
              f"{v['cpu']:.2f} | {'yes' if v['same'] else 'NO'} | {'met' if met else 'MISSED'} |")
    peak = max(v["peak_kb"] for v in res.values()) / 1024
    cpu = max(v["cpu"] for v in res.values())
    print(f"\n{len(CASES)} cases, all targets {'met' if ok_all else 'NOT met'}; worst peak {peak:.0f} MB, "
          f"worst CPU {cpu:.2f} s; whole run {wall:.1f} s wall; load average {open('/proc/loadavg').read().split()[:3]}")
    return 0 if ok_all else 1


if __name__ == "__main__":
    sys.exit(main())
