"""Where the mirror-pair rule acts (calib_core.detect.image.mirror; issue 11, helper tank2).

The rule only turns a set of round outlines into one object when one of them is the mirror copy
of a nearer one; an image where no copy is set aside is decided exactly as without the rule. So
running the detector once per image and listing the images where a copy was set aside (a spy on
``detect._mirror_copy_of``) shows every change the rule makes, and whether each is right: the
ball found within 3 px (right), found elsewhere (wrong), a ball-free image with a find (false),
or still refused.

Run: .venv/bin/python benchmarks/bench_mirror_pairs.py --kinds tank [--seeds N] [--first K]
     [--scale S] [--cache DIR]  (cache as bench_image_presets.py's)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchmarks.bench_image_presets as presets  # noqa: E402
from calib_core.detect.image import detect as D  # noqa: E402

TOL_PX = 3.0


class _Spy:
    """Counts the copies set aside during one detection."""

    def __init__(self):
        self.copies = 0
        self._orig = D._mirror_copy_of

    def __call__(self, look, far, near):
        k = self._orig(look, far, near)
        self.copies += k is not None
        return k


def _outcome(det, case, with_ball: bool) -> str:
    if not det.found:
        return "refused"
    if not with_ball:
        return "false"
    return "right" if np.hypot(*(det.center_uv_px - case.true_uv_px)) <= TOL_PX else "wrong"


def _run_kind(kind, seeds, scale, spy, rows, lines) -> None:
    n, counts = 0, {"right": 0, "wrong": 0, "false": 0, "refused": 0}
    for seed in seeds:
        for with_ball in (True, False):
            case = presets._case(kind, seed, scale, with_ball)
            spy.copies = 0
            det = D.detect_sphere_in_image(case.image, case.cam, case.radius_m)
            n += 1
            if spy.copies:
                out = _outcome(det, case, with_ball)
                counts[out] += 1
                lines.append(f"{case.label} ball={with_ball} {out} score={det.score or 0:.2f} "
                             f"{det.reason or det.extras.get('mirror_copy', '')}")
    rows.append(f"| {kind} | {n} | {sum(counts.values())} | {counts['right']} | {counts['wrong']} | "
                f"{counts['false']} | {counts['refused']} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", default="tank")
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--first", type=int, default=1000)
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--cache", type=Path, default=None)
    a = ap.parse_args(argv)
    presets.CACHE = a.cache
    spy = _Spy()
    D._mirror_copy_of = spy
    rows: list[str] = []
    lines: list[str] = []
    for kind in a.kinds.split(","):
        _run_kind(kind, range(a.first, a.first + a.seeds), a.scale, spy, rows, lines)
    print("\n".join(lines))
    print(f"\nImages where a mirror copy was set aside (seeds {a.first}-{a.first + a.seeds - 1}, "
          "with and without the ball)")
    print("| kind | images | copy set aside | ball found right | found wrong | ball-free find | still refused |")
    print("|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
