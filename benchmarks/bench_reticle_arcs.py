"""A circle reticle drawn in arcs with gaps over "rov" frames (issue 11): is it taken for a ball?

Each frame of the held-out "rov" kind (with and without its ball) gets a white circle reticle
with a dark outline at the frame's centre, radius 0.32 of the height, drawn as 4 arcs that
cover a share of the circle (1.0: a whole circle; 0.7, 0.45: with gaps). Per share: the
ball-free frames where anything is found (false), the ball frames where the ball is found
within 3 px (hit), found elsewhere (false) or not found.

Run: .venv/bin/python benchmarks/bench_reticle_arcs.py [--seeds N] [--first K] [--scale S]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from calib_core.detect.image.detect import detect_sphere_in_image  # noqa: E402
from calib_core.synth.image_cases import render_case  # noqa: E402
from calib_core.synth.photo.rov_osd import broken_reticle  # noqa: E402

SHARES = (1.0, 0.7, 0.45)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--first", type=int, default=1000)
    ap.add_argument("--scale", type=float, default=0.25)
    a = ap.parse_args(argv)
    rows = {s: {"free_false": 0, "hit": 0, "false": 0, "miss": 0} for s in SHARES}
    for seed in range(a.first, a.first + a.seeds):
        free = render_case("rov", seed, a.scale, with_ball=False)
        ball = render_case("rov", seed, a.scale)
        for s in SHARES:
            f = detect_sphere_in_image(broken_reticle(free.image, s), free.cam, free.radius_m)
            rows[s]["free_false"] += int(f.found)
            d = detect_sphere_in_image(broken_reticle(ball.image, s), ball.cam, ball.radius_m)
            err = float(np.hypot(*(d.center_uv_px - ball.true_uv_px))) if d.found else None
            rows[s]["hit" if err is not None and err <= 3.0 else "false" if d.found else "miss"] += 1
            print(f"s{seed} share {s:.2f}: ball-free found={f.found} score={f.score:.2f} | ball "
                  f"err={'-' if err is None else f'{err:.2f}'} score={d.score:.2f} {d.reason[:60]}", flush=True)
    print(f"\nReticle in arcs over rov frames, seeds {a.first}-{a.first + a.seeds - 1}, scale {a.scale:g}")
    print("| drawn share of the circle | ball-free frames: found | ball frames: hit | found elsewhere | not found |")
    print("|---|---|---|---|---|")
    for s, r in rows.items():
        print(f"| {s:.2f} | {r['free_false']} of {a.seeds} | {r['hit']} | {r['false']} | {r['miss']} |")
    print("load average:", Path("/proc/loadavg").read_text().split()[:3])
    return 0


if __name__ == "__main__":
    sys.exit(main())
