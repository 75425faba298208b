"""Sonar detection in the dry-room `clutter` preset, per seed: captures found and centre error
against ground truth (mm). Usage: bench_room_sonar.py [--seeds 31 41 42 43] [--cache DIR]."""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import yaml

from calib_core.pipeline import SessionData, detect_session
from calib_core.session import load_session
from calib_core.synth.generate import generate_session


def _session(cache: Path, seed: int) -> Path:
    root = cache / f"clutter-s{seed}"
    if not (root / "ground_truth.yaml").exists():
        generate_session(root, "clutter", seed, scale=0.5)
    return root


def _row(root: Path, seed: int) -> str:
    gt = yaml.safe_load((root / "ground_truth.yaml").read_text())["captures"]
    det = detect_session(SessionData(load_session(root)), {})
    errs, n_t, width = [], 0, float("nan")
    for cid, c in gt.items():
        if not c.get("target"):
            continue
        n_t += 1
        e = det.get(cid, {}).get("sonar", {})
        width = e.get("beam_width_deg", width)
        if e.get("center") is not None:
            errs.append(np.asarray(e["center"], float) - np.asarray(c["center_sonar_m"], float))
    if not errs:
        return f"{seed:>5}  {0:>2}/{n_t:<2}  {width:8.3f}      -      -      -"
    E = np.array(errs) * 1000
    return (f"{seed:>5}  {len(E):>2}/{n_t:<2}  {width:8.3f}  {np.linalg.norm(E.mean(0)):6.2f}  "
            f"{np.sqrt((E ** 2).sum(1).mean()):6.2f}  {np.linalg.norm(E, axis=1).max():6.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, nargs="+", default=[31, 41, 42, 43])
    ap.add_argument("--cache", type=Path, default=None, help="folder for generated sessions")
    a = ap.parse_args()
    cache = a.cache or Path(tempfile.mkdtemp())
    print("clutter preset (scale 0.5), sonar detection per session (mm)")
    print(" seed  found  width deg    bias     RMS     max")
    for s in a.seeds:
        print(_row(_session(cache, s), s))


if __name__ == "__main__":
    main()
