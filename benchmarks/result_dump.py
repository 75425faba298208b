"""Full-precision results of the detectors and the solver, to check that a speed-up changes none.

Dumps, for the code on PYTHONPATH, to a JSON file:
- sessions: a fresh ``calibrate_session`` (detection included) of synthetic sessions (generated
  once into --cache): every detection entry (unrounded: the detector's own dataclass fields) and
  calibration.json's numbers;
- images: ``detect_sphere_in_image`` on bench_image_presets cases (--kinds, --seeds, --scale;
  rendered once into --cache): found, centre, covariance, score, reason, ellipse, radius, range,
  method and the extras.
Timing fields (``*_ms``, ``created``, ``detected_at``, the detector's code digest) are left out.
``--compare A.json B.json`` prints every value that differs beyond --tol (absolute, relative to
max(1, |value|)); 0 means bit-identical.

    PYTHONPATH=OLD .venv/bin/python benchmarks/result_dump.py --out old.json [--sessions canal:1] [--kinds clutter,rov]
    PYTHONPATH=NEW .venv/bin/python benchmarks/result_dump.py --out new.json ...
    .venv/bin/python benchmarks/result_dump.py --compare old.json new.json [--tol 1e-9]
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SKIP = ("_ms", "created", "detected_at", "detector", "digest", "time_s")  # digest: it hashes the code


def plain(x):
    """JSON-able copy of ``x`` with floats kept exact (repr round-trips) and timing fields dropped."""
    if isinstance(x, dict):
        return {str(k): plain(v) for k, v in x.items() if not str(k).endswith(SKIP)}
    if isinstance(x, (list, tuple)):
        return [plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return plain(x.tolist())
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(x) else repr(float(x))
    if isinstance(x, (np.integer, np.bool_)):
        return x.item()
    if hasattr(x, "__dataclass_fields__"):
        return plain({k: getattr(x, k) for k in x.__dataclass_fields__})
    return x


def session_results(cache: Path, spec: str) -> dict:
    from calib_core.detections import load_detections
    from calib_core.pipeline import SessionData, detect_session
    from calib_core.session import load_session
    from calib_core.solve.calibrate import calibrate_session
    from calib_core.synth.generate import generate_session

    preset, seed = spec.split(":")
    src = cache / f"{preset}-{seed}"
    if not (src / "session.yaml").exists():
        generate_session(src, preset, int(seed))
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "s"
        shutil.copytree(src, root)
        (root / "detections.yaml").unlink(missing_ok=True)
        s = load_session(root)
        data = SessionData(s)
        dets = detect_session(data, load_detections(s))
        cal = calibrate_session(load_session(root), load_detections(s), {"detect": True})
    return {"detections": plain(dets), "calibration": plain(cal), "beam_width_deg": data.beam_width_deg}


def image_results(cache: Path, kinds: list[str], seeds: list[int], scale: float) -> dict:
    import benchmarks.bench_image_presets as bip
    from calib_core.detect.image.detect import detect_sphere_in_image

    bip.CACHE = cache
    out = {}
    for kind in kinds:
        for seed in seeds:
            case = bip._case(kind, seed, scale)
            det = detect_sphere_in_image(case.image, case.cam, case.radius_m, background=case.background)
            out[f"{kind}:{seed}"] = plain(det)
    return out


def compare(a, b, tol: float, path: str = "") -> list[str]:
    """Every difference between two dumps, as 'path: a != b'."""
    if isinstance(a, dict) and isinstance(b, dict):
        a, b = ({k: v for k, v in d.items() if not k.endswith(SKIP)} for d in (a, b))
        out = [f"{path}/{k}: only in {'A' if k in a else 'B'}" for k in sorted(set(a) ^ set(b))]
        for k in sorted(set(a) & set(b)):
            out += compare(a[k], b[k], tol, f"{path}/{k}")
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: length {len(a)} != {len(b)}"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in compare(x, y, tol, f"{path}[{i}]")]
    if isinstance(a, float) and isinstance(b, (int, float)) or isinstance(b, float) and isinstance(a, (int, float)):
        return [] if abs(a - b) <= tol * max(1.0, abs(a)) else [f"{path}: {a!r} != {b!r}"]
    return [] if a == b else [f"{path}: {a!r} != {b!r}"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path)
    ap.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "sonarcal_dump_cache")
    ap.add_argument("--sessions", default="canal:1", help="preset:seed,... ('' for none)")
    ap.add_argument("--kinds", default="", help="bench_image_presets kinds, comma-separated")
    ap.add_argument("--seeds", default="1000", help="image case seeds, e.g. 1000-1002")
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--compare", nargs=2, type=Path, metavar=("A", "B"))
    ap.add_argument("--tol", type=float, default=0.0)
    a = ap.parse_args(argv)
    if a.compare:
        da, db = (json.loads(p.read_text()) for p in a.compare)
        diffs = compare(da, db, a.tol)
        n = sum(len(v) for part in da.values() for v in [part])
        print(f"{len(diffs)} differences beyond {a.tol:g} ({n} top-level results compared)")
        for d in diffs[:50]:
            print("  " + d)
        return 1 if diffs else 0
    lo, _, hi = a.seeds.partition("-")
    seeds = list(range(int(lo), int(hi or lo) + 1))
    out = {"sessions": {s: session_results(a.cache, s) for s in a.sessions.split(",") if s}}
    kinds = [k for k in a.kinds.split(",") if k]
    out["images"] = image_results(a.cache / "images", kinds, seeds, a.scale) if kinds else {}
    a.out.write_text(json.dumps(out, sort_keys=True))
    print(f"wrote {a.out}: {len(out['sessions'])} sessions, {len(out['images'])} images")
    return 0


if __name__ == "__main__":
    sys.exit(main())
