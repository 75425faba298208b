"""Image detection alone on generated sessions of the holder / room presets, against the truth.

For each preset and seed a session is generated (``calib_core.synth.generate``; cached in
``--cache`` so that a second run only re-detects), and every camera image goes through
:func:`calib_core.detect.image.detect.detect_sphere_in_image` with the session's background when it
has one (no sonar-guided second look: the image side on its own). Against the ground truth:

- "right": found within 3 px of the true projection of the sphere centre;
- "wrong": found, but more than 3 px off (or where the ball is not in the image);
- "missed": the whole ball is visible (truth ``visible``) and nothing was found;
- wrong detections at or above a score of 0.5 are listed by name ("confident wrong").

Also the reliability table of the scores (right = within 3 px).

Run: .venv/bin/python benchmarks/bench_image_sessions.py [--presets P ...] [--seeds 41-60]
     [--scale 0.5] [--cache DIR] [--list] [--flow]

``--flow``: the entries after the whole session flow instead (see ``benchmarks/image_flow.py``):
right / wrong / wrong used in a solve / missed with reasons / second-look entries.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from calib_core.detect.image.detect import detect_sphere_in_image  # noqa: E402
from calib_core.detect.image.score import reliability_table  # noqa: E402
from calib_core.detect.reasons import reason_kind  # noqa: E402
from calib_core.io.images import load_image  # noqa: E402
from calib_core.pipeline import SessionData  # noqa: E402
from calib_core.session import load_session  # noqa: E402
from calib_core.synth.generate import generate_session  # noqa: E402
from calib_core.synth.ground_truth import load_ground_truth  # noqa: E402

PRESETS = ("lidar-chair", "rgbd-stick", "rgbd-table", "clutter", "seabed-slab", "gym", "carried-photo")
TOL_PX = 3.0
CONFIDENT = 0.5


def session_dir(cache: Path, preset: str, seed: int, scale: float) -> Path:
    """The cached session folder (generated on first use)."""
    root = cache / f"{preset}-s{seed}-x{scale:g}"
    if not (root / "ground_truth.yaml").is_file():
        generate_session(root, preset, seed, scale=scale)
    return root


def judge(det, truth: dict) -> str:
    """'right', 'wrong', 'missed' or 'ok-absent' for one detection against one image's truth."""
    uv = truth.get("center_uv_px")
    if det.found:
        if uv is not None and np.hypot(*(det.center_uv_px - np.asarray(uv, float))) <= TOL_PX:
            return "right"
        return "wrong"
    return "missed" if truth.get("visible") else "ok-absent"


def run_session(root: Path, preset: str, seed: int, st: dict, listing: bool) -> None:
    data = SessionData(load_session(root))
    gt = load_ground_truth(root)
    for cap in data.session.captures:
        for cam, path in cap.image_paths.items():
            model = data.camera(cam)
            img = load_image(path, (model.width_px, model.height_px))
            t0 = time.perf_counter()
            det = detect_sphere_in_image(img, model, data.session.sphere_radius_m, background=data.background(cam))
            st["ms"].append(1e3 * (time.perf_counter() - t0))
            truth = gt["captures"][cap.id]["images"][cam]
            verdict = judge(det, truth)
            st[verdict] += 1
            if "motion_px" in gt["captures"][cap.id]:  # photographic presets: recall by motion blur
                st["by_blur"][blur_class(gt["captures"][cap.id]["motion_px"])][verdict] += 1
            st["visible"] += bool(truth.get("visible"))
            name = f"{preset} s{seed} {cap.id} {cam}"
            if det.found:
                st["scored"].append((det.score, verdict == "right"))
            if verdict == "right":
                st["right_off"].append(float(np.hypot(*(det.center_uv_px - np.asarray(truth["center_uv_px"], float)))))
            if verdict == "wrong":
                uv = truth.get("center_uv_px")
                off = np.hypot(*(det.center_uv_px - uv)) if uv is not None else float("nan")
                st["wrong_list"].append((det.score, name, off))
            if verdict == "missed":
                st["miss_reasons"][reason_kind(det.reason)] += 1
                st["miss_list"].append(f"{name}: {det.reason}")
            if listing:
                print(f"{name:32s} vis={truth.get('visible')!s:5s} {verdict:9s} score={det.score:.2f} {det.reason}",
                      flush=True)


def new_stats() -> dict:
    return {"right": 0, "wrong": 0, "missed": 0, "ok-absent": 0, "visible": 0, "ms": [], "scored": [], "right_off": [],
            "by_blur": defaultdict(Counter),
            "wrong_list": [], "miss_reasons": Counter(), "miss_list": []}


def print_table(rows: dict, seeds, scale: float) -> None:
    print(f"\nImage detection alone on generated sessions, seeds {seeds[0]}-{seeds[-1]}, scale {scale:g} "
          f"(right = within {TOL_PX:.0f} px of the truth)")
    print("| preset | images | whole ball visible | right | wrong | of them score >= 0.5 | missed (visible) "
          "| misses (reason: count) | ms/image (median) | centre RMS of right (px) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for preset, st in rows.items():
        n = st["right"] + st["wrong"] + st["missed"] + st["ok-absent"]
        conf = sum(1 for s, _, _ in st["wrong_list"] if s >= CONFIDENT)
        miss = ", ".join(f"{k}: {v}" for k, v in st["miss_reasons"].most_common()) or "-"
        print(f"| {preset} | {n} | {st['visible']} | {st['right']} | {st['wrong']} | {conf} | {st['missed']} "
              f"| {miss} | {np.median(st['ms']):.1f} | {_rms(st['right_off'])} |")
    wrong = sorted((w for st in rows.values() for w in st["wrong_list"]), reverse=True)
    print("\nWrong detections (score, image, px off), most confident first:")
    for s, name, off in wrong[:30]:
        print(f"  {s:.2f}  {name}  {off:.0f} px{'   <- confident' if s >= CONFIDENT else ''}")
    if not wrong:
        print("  none")


BLUR_CLASSES = ("still", "<= 4 px", "4-8 px", "> 8 px")


def blur_class(motion_px) -> str:
    """The class of a capture's motion blur (its length in px at the session's scale)."""
    if motion_px is None:
        return BLUR_CLASSES[0]
    b = float(np.hypot(*motion_px))
    return BLUR_CLASSES[1] if b <= 4 else BLUR_CLASSES[2] if b <= 8 else BLUR_CLASSES[3]


def print_blur_table(rows: dict) -> None:
    """Right / wrong / missed per motion-blur class (presets whose truth records the blur)."""
    lines = []
    for preset, st in rows.items():
        for cls in BLUR_CLASSES:
            c = st["by_blur"].get(cls)
            if c:
                n = sum(c.values())
                lines.append(f"| {preset} | {cls} | {n} | {c['right']} ({100 * c['right'] / n:.0f} %) | {c['wrong']} "
                             f"| {c['missed']} |")
    if lines:
        print("\nBy motion blur of the ball during the exposure (length at this scale)")
        print("| preset | blur | images | right | wrong | missed |")
        print("|---|---|---|---|---|---|")
        print("\n".join(lines))


def _rms(offsets: list) -> str:
    return f"{np.sqrt(np.mean(np.square(offsets))):.3f}" if offsets else "-"


def parse_seeds(text: str) -> list[int]:
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(x) for x in text.split(",")]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", nargs="+", default=list(PRESETS))
    ap.add_argument("--seeds", default="41-60", help="'41-60' or '41,43,50'")
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--cache", default="/tmp/sonarcal-image-sessions", help="folder for generated sessions")
    ap.add_argument("--list", action="store_true")
    ap.add_argument("--flow", action="store_true",
                    help="judge the entries after detect_session (with the sonar-guided second look) and the solve")
    a = ap.parse_args(argv)
    seeds = parse_seeds(a.seeds)
    cache = Path(a.cache)
    rows = {}
    if a.flow:
        return flow_main(a, seeds, cache)
    for preset in a.presets:
        st = rows[preset] = new_stats()
        for seed in seeds:
            run_session(session_dir(cache, preset, seed, a.scale), preset, seed, st, a.list)
    print_table(rows, seeds, a.scale)
    print_blur_table(rows)
    print(reliability_table([x for st in rows.values() for x in st["scored"]],
                            "Reliability of the detection score (all presets; right = within 3 px)"))
    print("load average:", Path("/proc/loadavg").read_text().split()[:3])
    return 0


def flow_main(a, seeds, cache: Path) -> int:
    from benchmarks.image_flow import new_flow_stats, print_flow_table, run_flow_session

    rows = {}
    for preset in a.presets:
        st = rows[preset] = new_flow_stats()
        for seed in seeds:
            run_flow_session(session_dir(cache, preset, seed, a.scale), f"{preset} s{seed}", st, a.list)
    print_flow_table(rows, seeds, a.scale)
    print("load average:", Path("/proc/loadavg").read_text().split()[:3])
    return 0


if __name__ == "__main__":
    sys.exit(main())
