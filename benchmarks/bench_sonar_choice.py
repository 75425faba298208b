"""Session-level choice between sonar candidates ("two candidates"), measured on sweep sessions.

Runs :func:`calib_core.pipeline.detect_session` (as ``sonarcal detect`` does) on the sweep
sessions of ``bench_detection_range.py --sweep`` whose per-capture detection refused clouds
as "two candidates" (seabed s49, seabed-slab s51 and s60, clutter s57 at scale 0.5). Two tables:
1. the sweep's sessions (``--cache``; generated there when missing) with blank images, as the
   sweep makes them (the range side never reads them): only the static-scenery cue can decide;
2. the same sessions generated in full, images rendered (``--full-cache``; slow the first time,
   about 45 s a session): both cues. Skipped with ``--no-full``.
Per session: the captures with the target, those refused per capture (before), those the
session-level choice settled (right / wrong: the centre within 2 cm of the truth or not), and
those still refused (after).

    .venv/bin/python benchmarks/bench_sonar_choice.py [--cache /tmp/sonar2/sweep]
        [--full-cache /tmp/sonar2/full] [--no-full] [--workers 1]

``--entries DIR [DIR ...]``: instead, the static-scenery cue's thresholds measured on the sonar
entries ``bench_detection_range.py --sweep --dump DIR`` wrote (many seeds and presets, no
detection run here): every capture whose entry records two or more round objects of the
sphere's size ("two candidates", or a clear winner and what it beat) is settled with each
pair of shares (STATIC_SHARE x MOVING_SHARE) as :mod:`calib_core.disambiguate.sonar` does;
right = the candidate taken is within a radius of the truth. For the clear winners (third
table) a change is right when the winner was not the target and the loser taken is.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_detection_range import SWEEP_PRESETS, _sweep_session  # noqa: E402

from calib_core.pipeline import detect_session  # noqa: E402
from calib_core.session import load_session  # noqa: E402
from calib_core.synth.generate import generate_session  # noqa: E402
from calib_core.synth.ground_truth import load_ground_truth  # noqa: E402

SESSIONS = [("seabed", 49), ("seabed-slab", 60), ("seabed-slab", 51), ("clutter", 57)]
RIGHT_M = 0.02


def one(root: Path, workers: int) -> dict:
    """Counts for one session."""
    gt = load_ground_truth(root)
    dets = detect_session(load_session(root), {}, workers=workers)
    out = {"n": 0, "before": 0, "right": 0, "wrong": 0, "after": 0, "why": []}
    for cid, c in gt["captures"].items():
        e = dets.get(cid, {}).get("sonar", {})
        if not c.get("target"):  # nothing to find: a settled entry there is a wrong one
            out["wrong"] += bool(e.get("resolved_by"))
            continue
        out["n"] += 1
        if e.get("resolved_by"):
            out["before"] += 1
            err = np.linalg.norm(np.asarray(e["center"], float) - np.asarray(c["center_sonar_m"], float))
            out["right" if err <= RIGHT_M else "wrong"] += 1
            out["why"].append(f"  {cid}: {err * 1000:.1f} mm, {e['resolved_by']}")
        elif e.get("center") is None:
            out["before"] += 1
            out["after"] += 1
            out["why"].append(f"  {cid}: still refused: {e.get('reason', '?')[:110]}")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", type=Path, default=Path("/tmp/sonar2/sweep"))
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--full-cache", type=Path, default=Path("/tmp/sonar2/full"))
    ap.add_argument("--no-full", action="store_true", help="only the blank-image sessions")
    ap.add_argument("--all", action="store_true", help="also every preset of the sweep, seeds 41-60 (slow)")
    ap.add_argument("--entries", type=Path, nargs="+", default=None,
                    help="measure the scenery cue's shares on these dumps of sweep entries instead")
    ap.add_argument("--sessions", nargs="+", default=None, metavar="PRESET:SEED",
                    help="these sessions instead of the four of the sweep 41-60 (e.g. carried:62)")
    args = ap.parse_args(argv)
    if args.sessions:
        SESSIONS[:] = [(p, int(s)) for p, s in (a.split(":") for a in args.sessions)]
    if args.entries:
        from bench_scenery_shares import shares_tables

        shares_tables(args.entries)
        return 0
    print("Blank images (the sweep's sessions): the static-scenery cue only")
    table(lambda p, s: _sweep_session(args.cache, p, s, args.scale), args.workers)
    if args.all:
        print("\nEvery sweep session (seeds 41-60, blank images): found per capture -> after the session's choice")
        sweep_all(args.cache, args.scale, args.workers)
    if not args.no_full:
        print("\nImages rendered: the static-scenery cue, then the images")
        table(lambda p, s: _full_session(args.full_cache, p, s, args.scale), args.workers)
    return 0


def _full_session(cache: Path, preset: str, seed: int, scale: float) -> Path:
    root = cache / f"{preset}-s{seed}"
    if not (root / "session.yaml").is_file() or load_ground_truth(root) is None:
        generate_session(root, preset, seed, scale=scale)
    return root


def table(session_root, workers: int) -> None:
    """One table over SESSIONS; ``session_root(preset, seed)`` gives each session's folder."""
    print(f"{'session':18} {'captures':>8} {'refused before':>14} {'settled right':>13} {'wrong':>5} "
          f"{'refused after':>13} {'s':>5}")
    tot = dict.fromkeys(("n", "before", "right", "wrong", "after"), 0)
    notes = []
    for preset, seed in SESSIONS:
        t0 = time.perf_counter()
        r = one(session_root(preset, seed), workers)
        for k in tot:
            tot[k] += r[k]
        notes += [f"{preset} s{seed}:"] + r["why"]
        print(f"{preset + ' s' + str(seed):18} {r['n']:8d} {r['before']:14d} {r['right']:13d} {r['wrong']:5d} "
              f"{r['after']:13d} {time.perf_counter() - t0:5.0f}")
    print(f"{'total':18} {tot['n']:8d} {tot['before']:14d} {tot['right']:13d} {tot['wrong']:5d} {tot['after']:13d}")
    print("\n".join(notes))


def sweep_all(cache: Path, scale: float, workers: int) -> None:
    """Totals per preset over seeds 41-60 (any refusal reason counts as not found)."""
    print(f"{'preset':12} {'captures':>8} {'found before':>12} {'settled right':>13} {'wrong':>5} {'found after':>11}")
    for preset in SWEEP_PRESETS:
        tot = dict.fromkeys(("n", "before", "right", "wrong", "after"), 0)
        for seed in range(41, 61):
            r = one(_sweep_session(cache, preset, seed, scale), workers)
            for k in tot:
                tot[k] += r[k]
        print(f"{preset:12} {tot['n']:8d} {tot['n'] - tot['before']:12d} {tot['right']:13d} {tot['wrong']:5d} "
              f"{tot['n'] - tot['after'] - tot['wrong']:11d}")


if __name__ == "__main__":
    sys.exit(main())
