"""Back surfaces in calib_core.fusion's z-buffer: a copy of every coloured point pushed a gap
further along its camera ray must stay uncoloured (the test_fusion_synth check, over more seeds).

For synthetic flange sessions (calib_core.synth, scale 0.25, 1 deg pan step, as the tests) and
gaps of 0.1-0.4 m: front points coloured alone, back copies that take a colour (leaks; target 0),
and front points whose colouring changes once the back copies are added.

    .venv/bin/python benchmarks/bench_fusion_backsurface.py [--seeds 8] [--cache DIR]

Sessions are generated into --cache (default: a temporary folder) and reused when present, so
two code versions can be compared on the same clouds (run each with its own PYTHONPATH).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._table import print_table  # noqa: E402
from calib_core import fusion as F  # noqa: E402
from calib_core.geometry import invert_T  # noqa: E402
from calib_core.io.clouds import load_cloud  # noqa: E402
from calib_core.io.images import load_image  # noqa: E402
from calib_core.session import load_session  # noqa: E402
from calib_core.synth.generate import generate_session  # noqa: E402
from calib_core.synth.ground_truth import load_ground_truth  # noqa: E402

GAPS_M = (0.1, 0.2, 0.4)


def _view(root: Path, seed: int):
    """cam1's model, true T_cam_sonar, cloud and image of the first flange (non-target) capture."""
    if not (root / "session.yaml").is_file() or load_ground_truth(root) is None:
        generate_session(root, "flange", seed, scale=0.25, pan_step_deg=1.0, sub_rays=9, n_captures=2,
                         n_flange=1, n_backgrounds=0)
    s, gt = load_session(root), load_ground_truth(root)
    cap = next(c for c in s.captures if not gt["captures"][c.id].get("target"))
    T = np.asarray(gt["cameras"]["cam1"]["T_cam_sonar"], float)
    return s.camera_model("cam1"), T, load_cloud(cap.cloud_path).points_m, load_image(cap.image_paths["cam1"])


def _leaks(cam, T, P, img, gap_m: float) -> tuple[int, int, int]:
    """(front coloured, back copies coloured behind a coloured front point, front points changed)."""
    _, ok = F.colour_cloud(P, img, cam, T)
    rays = P - invert_T(T)[:3, 3]
    back = P + gap_m * rays / np.linalg.norm(rays, axis=1, keepdims=True)
    _, ok2 = F.colour_cloud(np.vstack([P, back]), img, cam, T)
    n = len(P)
    return int(ok.sum()), int((ok2[n:] & ok).sum()), int((ok2[:n] != ok).sum())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--cache", type=Path, default=None)
    args = ap.parse_args(argv)
    cache = args.cache or Path(tempfile.mkdtemp(prefix="bench_backsurface_"))
    rows, total = [], {g: [0, 0, 0] for g in GAPS_M}
    for seed in range(1, args.seeds + 1):
        cam, T, P, img = _view(cache / f"flange{seed}", seed)
        row = [seed]
        for g in GAPS_M:
            front, leak, changed = _leaks(cam, T, P, img, g)
            row += [front, leak, changed] if g == GAPS_M[0] else [leak, changed]
            total[g] = [total[g][0] + front, total[g][1] + leak, total[g][2] + changed]
        rows.append(row)
    g0 = GAPS_M[0]
    rows.append(["all", total[g0][0], *(v for g in GAPS_M for v in total[g][1:])])
    head = ["seed", "front coloured"]
    for g in GAPS_M:
        head += [f"leaks {g:g} m", f"front changed {g:g} m"]
    print(f"fusion back-surface benchmark: flange sessions, cam1, {args.seeds} seeds "
          f"(cpus: {os.cpu_count()}, load: {os.getloadavg()[0]:.2f})")
    print_table(head, rows)
    leaks = sum(total[g][1] for g in GAPS_M)
    print(f"target no back copy coloured: {'met' if leaks == 0 else 'MISSED'} ({leaks} leaks over all gaps)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
