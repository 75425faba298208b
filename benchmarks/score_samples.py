"""Labelled detections for fitting and measuring the image detection's score (issue 11).

Every record is one accepted outline: the raw extras the score model reads, the apparent
radius, whether the look was hinted (the sonar-guided / clicked look), and whether it was right
(within 3 px of the true or hand-checked centre). Sources, and which seeds are which:

- ``cases``: :mod:`calib_core.synth.image_cases` (clutter, big, turbid, chair), rendered with
  and without the ball, with and without the background where there is one. TRAINING seeds
  0-39; TEST seeds 1000-1039 (the held-out seeds of ``bench_image_presets.py``).
- ``sessions``: generated sessions of the holder / room presets (``bench_image_sessions.py``
  presets, plus ``decoys`` and ``review``). TRAINING seeds 1-3; TEST seeds 41-60.
- ``kinectnet``: the real photographs of ``../shared/data/kinectnet-dev`` against the hand
  check; TEST only, never fitted to.

Hard negatives (``hard=True``, training only): the detector's verification run as the
sonar-guided look runs it (``hint_uv_px`` / ``hint_radius_px``) at the places of the other
round things in the image - every coarse candidate (round-outline votes and region contrast)
that is not the ball - and at the ball's own place with a wrong radius (0.6x and 1.6x). Each
hinted outline that is accepted is a sample, labelled by the truth like any other; most of
them are wrong-but-plausible outlines (decoys, chair and table parts, lamps, tiles), the kind
of wrong answer the free search rarely leaves in synthetic training images.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from calib_core.detect.image import detect as image_det  # noqa: E402
from calib_core.detect.image.detect import detect_sphere_in_image  # noqa: E402
from outline_cues import CUE_NAMES, outline_cues  # noqa: E402

TOL_PX = 3.0
FIELDS = ("outline_coverage", "edge_rms_px", "outside_mismatch", "edge_contrast", "runner_up_ratio",
          "radius_px", "fit_quality", "hinted", "right", "score_now")
# score round 3: more of the extras and the image cues around the outline (outline_cues.py);
# records collected before have NaN there
MORE_FIELDS = ("support", "edge_points", "inliers", "refined", "centre_err_px") + CUE_NAMES
ALL_FIELDS = FIELDS + MORE_FIELDS
MAX_HARD = 5  # hinted looks per image at other round things


def record(det, truth_uv, hinted: bool, img=None) -> list[float]:
    """One record (FIELDS order; with ``img``, ALL_FIELDS) of a found detection."""
    e = det.extras
    err = float(np.hypot(*(det.center_uv_px - truth_uv))) if truth_uv is not None else np.inf
    right = err <= TOL_PX
    base = [float(e.get("outline_coverage", 0.0)), float(e.get("edge_rms_px", 0.0)),
            float(e.get("outside_mismatch", 0.0)), float(e.get("edge_contrast", 0.0)),
            float(e.get("runner_up_ratio", 0.0)), float(det.radius_px), float(e.get("fit_quality", 0.0)),
            float(hinted), float(right), float(det.score)]
    if img is None:
        return base
    cues = outline_cues(img, det.center_uv_px, det.radius_px)
    return base + [float(e.get(k, np.nan)) for k in ("support", "edge_points", "inliers", "refined")] + [
        min(err, 1e6)] + [cues[k] for k in CUE_NAMES]


def photo_records(kinds, seeds, scale: float, case_of, log=print) -> np.ndarray:
    """ALL_FIELDS records of the free detection on the photographic kinds (glossy, panels,
    motion), with and without the ball (a detection on a ball-free image is wrong);
    ``case_of(kind, seed, scale, with_ball)`` renders or loads a case."""
    rows = []
    for kind in kinds:
        for seed in seeds:
            for with_ball in (True, False):
                case = case_of(kind, seed, scale, with_ball)
                det = detect_sphere_in_image(case.image, case.cam, case.radius_m, background=case.background)
                if det.found:
                    rows.append(record(det, case.true_uv_px if with_ball else None, False, case.image))
        log(f"  photo {kind} s{seeds[0]}-{seeds[-1]}: {len(rows)} records")
    return np.array(rows, float).reshape(-1, len(ALL_FIELDS))


def _coarse_places(img, cam, radius_m, background):
    """(centre_px, radius_px) of the coarse candidates of one image (votes / background blobs,
    then region contrast): the places of the round things a look could verify."""
    look = image_det._Look(img, cam, radius_m, background, image_det.DEFAULT_RANGE_LIMITS_M, None, None,
                           np.random.default_rng(0))
    cands = list(look.first_candidates(None))
    if background is None:
        cands += list(look.contrast_candidates())
    return [(np.asarray(c.centre_px, float), float(c.radius_px)) for c in cands]


def image_records(img, cam, radius_m, background, truth_uv, truth_r, hard: bool) -> list[list[float]]:
    """The free detection of one image and, with ``hard``, the hinted looks at other places."""
    out = []
    det = detect_sphere_in_image(img, cam, radius_m, background=background)
    if det.found:
        out.append(record(det, truth_uv, False, img))
    if not hard:
        return out
    bg = image_det.prepare_background(background) if background is not None else None
    hints = []
    for c, r in _coarse_places(img, cam, radius_m, bg):
        if truth_uv is not None and np.hypot(*(c - truth_uv)) < 0.5 * max(truth_r, r):
            continue  # the ball itself
        if all(np.hypot(*(c - h)) > 0.5 * r for h, _ in hints):
            hints.append((c, r))
    hints = hints[:MAX_HARD]
    if truth_uv is not None:
        hints += [(np.asarray(truth_uv, float), f * truth_r) for f in (0.6, 1.6)]
    for c, r in hints:
        d = detect_sphere_in_image(img, cam, radius_m, background=background, hint_uv_px=c, hint_radius_px=r)
        if d.found:
            out.append(record(d, truth_uv, True, img))
    return out


def case_records(kinds, seeds, scale: float, hard: bool, log=print, case_of=None) -> np.ndarray:
    """Records of the old kinds' cases; ``case_of(kind, seed, scale, with_ball)`` renders or
    loads a case (default: render_case)."""
    from calib_core.synth.image_cases import render_case

    case_of = case_of or (lambda k, s, sc, wb: render_case(k, s, sc, with_ball=wb))
    rows = []
    for kind in kinds:
        for seed in seeds:
            for with_ball in (True, False):
                case = case_of(kind, seed, scale, with_ball)
                uv = case.true_uv_px if with_ball else None
                for bg in ((case.background, None) if case.background is not None else (None,)):
                    rows += image_records(case.image, case.cam, case.radius_m, bg, uv, case.radius_px, hard)
            log(f"  cases {kind} s{seed}: {len(rows)} records")
    return np.array(rows, float).reshape(-1, len(ALL_FIELDS))


def session_records(presets, seeds, scale: float, cache: Path, hard: bool, log=print) -> np.ndarray:
    from bench_image_sessions import session_dir

    from calib_core.io.images import load_image
    from calib_core.pipeline import SessionData
    from calib_core.session import load_session
    from calib_core.synth.ground_truth import load_ground_truth

    rows = []
    for preset in presets:
        for seed in seeds:
            root = session_dir(cache, preset, seed, scale)
            data = SessionData(load_session(root))
            gt = load_ground_truth(root)
            for cap in data.session.captures:
                for cam, path in cap.image_paths.items():
                    model = data.camera(cam)
                    img = load_image(path, (model.width_px, model.height_px))
                    truth = gt["captures"][cap.id]["images"][cam]
                    uv = truth.get("center_uv_px")
                    uv = np.asarray(uv, float) if uv is not None else None
                    d = float(truth.get("distance_m") or 0.0)
                    R = data.session.sphere_radius_m
                    r = float(model.fx * np.tan(np.arcsin(min(R / d, 0.99)))) if d > R else 0.0
                    rows += image_records(img, model, data.session.sphere_radius_m, data.background(cam), uv,
                                          r, hard and uv is not None and r > 0)
            log(f"  sessions {preset} s{seed}: {len(rows)} records")
    return np.array(rows, float).reshape(-1, len(ALL_FIELDS))


def kinectnet_records(session_dir: Path, reference: Path) -> np.ndarray:
    """Free detections on the real photographs (right = whole ball within 3 px of the hand check)."""
    import yaml

    from calib_core.io.images import load_image
    from calib_core.session import load_session

    ses = load_session(session_dir)
    ref = yaml.safe_load(reference.read_text())
    rows = []
    for cam in sorted(ses.cameras):
        model = ses.camera_model(cam)
        for cap in ses.captures:
            r = ref[cam][cap.id]
            uv = np.asarray(r["centre_uv_px"], float) if r.get("centre_uv_px") and r["flag"] == "whole" else None
            rows += image_records(load_image(cap.image_paths[cam]), model, ses.sphere_radius_m, None, uv, 0.0,
                                  False)
    return np.array(rows, float).reshape(-1, len(ALL_FIELDS))
