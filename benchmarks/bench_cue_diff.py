"""Image by image: what one cue of the image detector changes (issue 11, held-out kinds).

Runs the detector on cached synthetic cases (``bench_image_presets.py --cache``) with the cue
on; where the cue proposed candidates, runs it again with the cue off and lists every image
whose result changed (found, error to the truth, score, reason). Prints, per kind, recall,
false detections and ball-free finds with the cue off and on. Cues: "pattern" (the fourth
cue, :mod:`calib_core.detect.image.pattern`), "closed" (the fifth, see-through balls,
:mod:`calib_core.detect.image.closing`: re-run only where it added fits).

Run: .venv/bin/python benchmarks/bench_cue_diff.py --kinds sports,outdoor --seeds 40 --cache DIR [--negatives] [--cue closed]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchmarks.bench_image_presets as bip  # noqa: E402
from calib_core.detect.image import detect as im  # noqa: E402

CALLED = []


def _pattern_spy(cands, r_bounds, most=3):
    out = CUES["pattern"][1](cands, r_bounds, most)
    CALLED.append(len(out))
    return out


def _pattern_off(cands, r_bounds, most=3):
    return []


def _closed_spy(look, cands, fits):
    out = CUES["closed"][1](look, cands, fits)
    CALLED.append(len(out[1]) - len(fits))  # (a discarded guess leaves the detection as it was)
    return out


def _closed_off(look, cands, fits):
    return cands, fits


# cue: (detect's attribute, the real function, spy that records whether it changed anything, off)
CUES = {"pattern": ("enclosing_candidates", im.enclosing_candidates, _pattern_spy, _pattern_off),
        "closed": ("_closed_cue", im._closed_cue, _closed_spy, _closed_off)}


def outcome(case, with_ball, bg=False):
    """What the detector makes of ``case`` (with its background frame when ``bg``): found, right
    (within bip.TOL_PX of the truth, ball present), error (px), score, reason."""
    det = im.detect_sphere_in_image(case.image, case.cam, case.radius_m, background=case.background if bg else None)
    err = float(np.hypot(*(det.center_uv_px - case.true_uv_px))) if det.found else None
    right = det.found and with_ball and err <= bip.TOL_PX
    return {"found": det.found, "right": right, "err": err, "score": det.score, "reason": det.reason}


def outcome_text(o):
    """One outcome as the image listings print it."""
    if not o["found"]:
        return f"missed ({o['reason']})"
    return f"{'hit' if o['right'] else 'WRONG'} err {o['err']:.2f} score {o['score']:.2f}" if o["err"] is not None \
        else f"found (ball-free) score {o['score']:.2f}"


def run(kinds, seeds, negatives, cue="pattern"):
    attr, real, spy, off_fn = CUES[cue]
    rows = []
    for kind in kinds:
        tally = {"off": [0, 0, 0], "on": [0, 0, 0]}  # hits, wrong with ball, ball-free finds
        n = nn = 0
        for seed in seeds:
            for wb in ((True, False) if negatives else (True,)):
                case = bip._case(kind, seed, 0.5, with_ball=wb)
                CALLED.clear()
                setattr(im, attr, spy)
                on = outcome(case, wb)
                off = on
                if any(CALLED):
                    setattr(im, attr, off_fn)
                    off = outcome(case, wb)
                setattr(im, attr, real)
                n, nn = n + wb, nn + (not wb)
                for key, o in (("off", off), ("on", on)):
                    if wb:
                        tally[key][0] += o["right"]
                        tally[key][1] += o["found"] and not o["right"]
                    else:
                        tally[key][2] += o["found"]
                if (off["found"], off["right"], off["err"]) != (on["found"], on["right"], on["err"]):
                    print(f"{case.label}{'' if wb else ' (ball-free)'}: {outcome_text(off)} -> {outcome_text(on)}")
        rows.append((kind, n, nn, tally))
    print("\n| kind | images | hits off -> on | wrong centres off -> on | ball-free finds off -> on |")
    print("|---|---|---|---|---|")
    for kind, n, nn, t in rows:
        print(f"| {kind} | {n} | {t['off'][0]} -> {t['on'][0]} | {t['off'][1]} -> {t['on'][1]} "
              f"| {t['off'][2]} -> {t['on'][2]} of {nn} |")
    print("load average:", Path("/proc/loadavg").read_text().split()[:3])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", required=True)
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--first", type=int, default=1000)
    ap.add_argument("--negatives", action="store_true")
    ap.add_argument("--cache", type=Path, required=True)
    ap.add_argument("--cue", choices=sorted(CUES), default="pattern")
    a = ap.parse_args(argv)
    bip.CACHE = a.cache
    run(a.kinds.split(","), range(a.first, a.first + a.seeds), a.negatives, a.cue)
    return 0


if __name__ == "__main__":
    sys.exit(main())
