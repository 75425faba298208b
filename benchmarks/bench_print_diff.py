"""Image by image: what the print rules of the image detector change (issue 11, patterned balls).

The rules (helper sports2): a fit wholly inside a larger body's outline is a print element
(:func:`calib_core.detect.image.pattern.lies_inside` in ``detect._good_fits``); a clear outline
inside a cluster of print candidates lets the pattern cue look (``detect._clear_in_print``), whose
enclosing candidate is not suppressed by a much smaller credible fit (``detect._print_cue``); a
several-edges outline needs edges at least as wide as the smoothing makes any step
(``fit.MIN_EDGE_WIDTH_PX``). Runs the detector on cached cases (``bench_image_presets.py
--cache``) with the rules on, records whether any rule made a difference to a decision; only
there runs it again with all of them off, and lists every image whose result changed (a case
with a background frame is run with it and without it, as bench_image_presets.py). Prints,
per kind, hits, wrong centres and ball-free finds with the rules off and on. Exact: where no
rule fired, off and on are the same computation.

Run: .venv/bin/python benchmarks/bench_print_diff.py --kinds sports --seeds 40 --first 1080 --cache DIR [--negatives]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchmarks.bench_image_presets as bip  # noqa: E402
from benchmarks.bench_cue_diff import outcome, outcome_text  # noqa: E402
from calib_core.detect.image import detect as im  # noqa: E402
from calib_core.detect.image import fit as fm  # noqa: E402

FIRED: list[str] = []
REAL = {"lies_inside": im.lies_inside, "_clear_in_print": im._clear_in_print, "_outline_held": fm._outline_held,
        "_new_candidates": im._new_candidates}
MIN_W = fm.MIN_EDGE_WIDTH_PX


def _spy_inside(f, g):
    out = REAL["lies_inside"](f, g)
    if out:
        FIRED.append("inside")
    return out


def _spy_print(look, cands, fits):
    out = REAL["_clear_in_print"](look, cands, fits)
    if out:
        FIRED.append("print")
    return out


def _spy_held(*a, **k):
    out = REAL["_outline_held"](*a, **k)
    fm.MIN_EDGE_WIDTH_PX = 0.0
    off = REAL["_outline_held"](*a, **k)
    fm.MIN_EDGE_WIDTH_PX = MIN_W
    if off != out:
        FIRED.append("width")
    return out


def _print_cue_old(look, cands, fits):
    """detect._print_cue before the rules (the fourth cue as the eighteenth round left it)."""
    more = REAL["_new_candidates"](fits, im.enclosing_candidates(cands, look.r_bounds))
    state = look.rng.bit_generator.state
    fourth = im._refine_all(look, more, False)
    if im._clear(fourth):
        return cands + more, fits + fourth
    look.rng.bit_generator.state = state
    return cands, fits


REAL_CUE = im._print_cue


def _spy_cue(look, cands, fits):
    enc = im.enclosing_candidates(cands, look.r_bounds)
    if len(REAL["_new_candidates"](fits, enc)) != len(im._new_candidates(
            [(c, f) for c, f in fits if not (f.credible and enc and all(
                im.MIN_GROWTH * im._mean_radius(f.silhouette_px) <= e.radius_px for e in enc))], enc)):
        FIRED.append("cue")
    return REAL_CUE(look, cands, fits)


def _rules(on: bool) -> None:
    im.lies_inside = _spy_inside if on else (lambda f, g: False)
    im._clear_in_print = _spy_print if on else (lambda look, cands, fits: False)
    fm._outline_held = _spy_held if on else REAL["_outline_held"]
    fm.MIN_EDGE_WIDTH_PX = MIN_W if on else 0.0
    im._print_cue = _spy_cue if on else _print_cue_old


def _one(case, wb, bg, tally):
    FIRED.clear()
    _rules(True)
    on = outcome(case, wb, bg)
    fired = sorted(set(FIRED))
    off = on
    if fired:
        _rules(False)
        off = outcome(case, wb, bg)
    _rules(True)
    for key, o in (("off", off), ("on", on)):
        if wb:
            tally[key][0] += o["right"]
            tally[key][1] += o["found"] and not o["right"]
            tally[key][3].append((o["score"], o["right"])) if o["found"] else None
            tally[key][4].append(o["err"]) if o["right"] else None
        else:
            tally[key][2] += o["found"]
            tally[key][3].append((o["score"], False)) if o["found"] else None
    if (off["found"], off["right"], off["err"]) != (on["found"], on["right"], on["err"]):
        print(f"{case.label}{'' if wb else ' (ball-free)'}{' bg' if bg else ''} [{','.join(fired)}]: {outcome_text(off)} -> {outcome_text(on)}", flush=True)


def _rms(errs) -> float:
    return float(np.sqrt(np.mean(np.square(errs)))) if errs else float("nan")


def run(kinds, seeds, negatives, scale):
    rows = []
    for kind in kinds:
        tally = {"off": [0, 0, 0, [], []], "on": [0, 0, 0, [], []]}  # hits, wrong, ball-free finds, scored, hit errors
        n = nn = 0
        for seed in seeds:
            for wb in ((True, False) if negatives else (True,)):
                case = bip._case(kind, seed, scale, with_ball=wb)
                for bg in ((True, False) if case.background is not None else (False,)):
                    n, nn = n + wb, nn + (not wb)
                    _one(case, wb, bg, tally)
        rows.append((kind, n, nn, tally))
    print("\n| kind | images | hits off -> on | wrong centres off -> on | ball-free finds off -> on "
          "| found at score >= 0.95 and wrong, off -> on | centre RMS of hits off -> on (px) |")
    print("|---|---|---|---|---|---|---|")
    for kind, n, nn, t in rows:
        hi = [sum(1 for s, r in t[k][3] if s >= 0.95 and not r) for k in ("off", "on")]
        print(f"| {kind} | {n} | {t['off'][0]} -> {t['on'][0]} | {t['off'][1]} -> {t['on'][1]} "
              f"| {t['off'][2]} -> {t['on'][2]} of {nn} | {hi[0]} -> {hi[1]} | {_rms(t['off'][4]):.3f} -> {_rms(t['on'][4]):.3f} |")
    print("load average:", Path("/proc/loadavg").read_text().split()[:3])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", required=True)
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--first", type=int, default=1000)
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--negatives", action="store_true")
    ap.add_argument("--cache", type=Path, required=True)
    a = ap.parse_args(argv)
    bip.CACHE = a.cache
    run(a.kinds.split(","), range(a.first, a.first + a.seeds), a.negatives, a.scale)
    return 0


if __name__ == "__main__":
    sys.exit(main())
