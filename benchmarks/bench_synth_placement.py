"""Synthetic placement for the presets whose sphere rests on or is held by something: for
every seed, does the generator place all targets, and does each camera see the sphere?

Prints one row per preset: seeds tried, seeds that failed to place, target images, images
with the sphere visible, the largest occluded fraction (ground_truth.yaml) and the wall time.
Generates at a tiny scale (placement and ground truth do not depend on the resolution).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from calib_core.synth.generate import generate_session
from calib_core.synth.ground_truth import load_ground_truth
from calib_core.synth.occlusion import MAX_OCCLUDED_FRACTION

HOLDER_PRESETS = ["seabed-slab", "rgbd-table", "lidar-chair", "rgbd-stick"]
TINY = dict(scale=0.08, pan_step_deg=3.0, sub_rays=3, n_backgrounds=0)


def preset_row(name: str, seeds, root: Path) -> str:
    t0 = time.time()
    failed, n_img, n_vis, worst = [], 0, 0, 0.0
    for s in seeds:
        try:
            out = generate_session(root / f"{name}-{s}", name, s, **TINY)
        except RuntimeError:
            failed.append(s)
            continue
        for cap in load_ground_truth(out)["captures"].values():
            for im in (cap["images"].values() if cap["target"] else ()):
                n_img += 1
                n_vis += bool(im["visible"] and im["occluded_fraction"] < MAX_OCCLUDED_FRACTION)
                worst = max(worst, im["occluded_fraction"])
    return (f"{name} | {len(seeds)} | {len(failed)} {failed if failed else ''} | {n_img} | {n_vis} | "
            f"{worst:.3f} | {time.time() - t0:.0f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs=2, default=[0, 61], help="first and one-past-last seed")
    ap.add_argument("--presets", nargs="+", default=HOLDER_PRESETS)
    a = ap.parse_args()
    seeds = list(range(*a.seeds))
    print(f"preset | seeds | placement failures | target images | seen (< {MAX_OCCLUDED_FRACTION:.0%} hidden) "
          "| worst occluded fraction | s")
    with tempfile.TemporaryDirectory() as tmp:
        for name in a.presets:
            print(preset_row(name, seeds, Path(tmp)), flush=True)


if __name__ == "__main__":
    main()
