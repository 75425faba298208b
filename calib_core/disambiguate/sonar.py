"""Choose between sonar candidates ("two candidates") with the rest of the session.

One cloud alone cannot tell the target from a scenery object of the same size (a rock, a
buoy, a pipe end). The session can, with two cues, tried in this order:

1. Static scenery: the target is moved between captures, the scenery is not. A candidate
   that sits (within a sphere radius) where a round object of the sphere's size is seen in
   many other captures' clouds (STATIC_SHARE; their found centres and the candidates their
   entries record)
   is scenery; when every candidate but one is scenery and that one is seen in few other
   captures, it is the target.
2. The images: the captures whose sonar and image detections are unambiguous give a rough
   rig registration (:func:`calib_core.disambiguate.image.resolve_candidates`, a 3D-3D RANSAC on
   the image centres read with the known radius). The candidate that lands on the capture's
   image detection (within the loose gate used there), while the others clearly do not, is
   the target.

A clear winner is re-examined the same way (:func:`reexamine_winners`): a cloud where a scenery
object beat the target (the ball far off, partly seen or noisier than the rock) records the
target among its ``other_candidates``; when the winner sits where a round object of the
sphere's size is seen in many other captures, one loser is seen in few, and no camera puts
the target on the winner, the loser is taken.

When neither cue decides, nothing is chosen and the refusal stays. Pure functions on
detections.yaml entries; :func:`calib_core.pipeline.detect_session` refits the choice.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_core.camera import CameraModel
from calib_core.disambiguate.image import candidate_points_cam_m, resolve_candidates

# A candidate seen in at least this share of the other captures (and in 2) is scenery: a
# scenery object of the target's size is not recorded in every cloud (it loses to the target
# by more than the detector's clear-winner ratio, or is not among the candidates judged).
STATIC_SHARE = 0.3
MOVING_SHARE = 0.2  # the target is seen in at most this share of the others (or in one)
STATIC_MARGIN = 2  # ... and in at least this many fewer than each scenery candidate
MIN_OTHERS = 3  # other captures needed before a share means anything


@dataclass(frozen=True)
class SonarChoice:
    """The candidate chosen for one capture (m, sonar frame) and the cue that decided."""

    center_sonar_m: np.ndarray
    resolved_by: str


def scenery_phrase(n_seen: int, n_others: int) -> str:
    """The ``resolved_by`` text of a choice made by the static-scenery cue."""
    return (f"static scenery: the other candidate sits where a round object of the sphere's size "
            f"is seen in {n_seen} of {n_others} other captures")


def winner_phrase(n_seen: int, n_others: int) -> str:
    """The ``resolved_by`` text when a clear winner was scenery and a loser was taken."""
    return (f"static scenery: the round object first chosen sits where one of the sphere's size "
            f"is seen in {n_seen} of {n_others} other captures; the sphere is the one that moves")


def image_phrase(cam: str) -> str:
    """The ``resolved_by`` text of a choice made by camera ``cam``'s image detection."""
    return f"camera {cam}: only this candidate lands on the image's detection (rough rig registration)"


def usable_entry(entry: dict | None) -> bool:
    return bool(entry) and entry.get("status") != "rejected"


def sightings_sonar_m(entry: dict | None) -> np.ndarray:
    """(K,3) every round object of the sphere's size one sonar entry records (m, sonar frame):
    its centre, its ``two_candidates`` and its ``other_candidates``."""
    if not usable_entry(entry):
        return np.zeros((0, 3))
    rows = [entry["center"]] if entry.get("center") is not None else []
    rows += list(entry.get("two_candidates") or []) + list(entry.get("other_candidates") or [])
    return np.asarray(rows, float).reshape(-1, 3)


def seen_counts(candidates_sonar_m: np.ndarray, others: dict[str, np.ndarray], radius_m: float) -> np.ndarray:
    """(K,) in how many of ``others``' sightings each candidate has a round object within
    ``radius_m``."""
    return np.array([sum(bool(len(o)) and bool(np.min(np.linalg.norm(o - c, axis=1)) <= radius_m)
                         for o in others.values()) for c in np.asarray(candidates_sonar_m, float)], int)


def choose_by_scenery(candidates_sonar_m: np.ndarray, others: dict[str, np.ndarray],
                      radius_m: float, static_share: float = STATIC_SHARE,
                      moving_share: float = MOVING_SHARE) -> tuple[int | None, str]:
    """(index of the target among ``candidates_sonar_m`` or None, the phrase saying why).

    ``others``: {capture_id: (K,3) sightings} of the session's other captures. The shares
    default to STATIC_SHARE and MOVING_SHARE (other values: ``bench_sonar_choice.py --entries``).
    """
    n = len(others)
    if n < MIN_OTHERS or len(candidates_sonar_m) < 2:
        return None, ""
    seen = seen_counts(candidates_sonar_m, others, radius_m)
    static = seen >= max(2, static_share * n)
    moving = seen <= max(1, moving_share * n)
    if moving.sum() == 1 and (static | moving).all() and seen[~moving].min() >= seen[moving][0] + STATIC_MARGIN:
        k = int(np.flatnonzero(moving)[0])
        return k, scenery_phrase(int(seen[~moving].min()), n)
    return None, ""


def rig_registration(cam: CameraModel, detections: dict, cam_name: str) -> np.ndarray | None:
    """Rough T_cam_sonar (4x4) from the captures whose sonar and ``cam_name`` image detections
    are both unambiguous (None when they do not agree on one)."""
    centers, cands = {}, {}
    for cid, d in detections.items():
        son, img = d.get("sonar"), d.get(cam_name)
        if usable_entry(son) and usable_entry(img) and son.get("center") is not None and img.get("center") is not None \
                and img.get("range_m"):
            centers[cid] = np.asarray(son["center"], float)
            cands[cid] = np.array([[*img["center"], img["range_m"]]], float)
    return resolve_candidates(cam, centers, cands).T_cam_sonar


def choose_by_image(candidates_sonar_m: np.ndarray, cam: CameraModel, T_cam_sonar: np.ndarray,
                    image_entry: dict | None) -> int | None:
    """Index of the only candidate that lands on the image detection (within the gate of
    :mod:`calib_core.disambiguate.image`, the others beyond twice it), else None."""
    if T_cam_sonar is None or not usable_entry(image_entry) or image_entry.get("center") is None \
            or not image_entry.get("range_m"):
        return None
    rng_m = float(image_entry["range_m"])
    P_cam_m = candidate_points_cam_m(cam, np.array([[*image_entry["center"], rng_m]]))[0]
    X_cam_m = np.asarray(candidates_sonar_m, float) @ T_cam_sonar[:3, :3].T + T_cam_sonar[:3, 3]
    d = np.linalg.norm(X_cam_m - P_cam_m, axis=1) / (0.05 * rng_m + 0.03)
    order = np.argsort(d)
    if len(d) >= 2 and d[order[0]] <= 1.0 and d[order[1]] > 2.0:
        return int(order[0])
    return None


def choose_sonar_candidates(detections: dict, cams: dict[str, CameraModel], radius_m: float,
                            ambiguous) -> dict[str, SonarChoice]:
    """{capture_id: choice} for the captures of ``ambiguous`` whose sonar entry records
    ``two_candidates`` and that one cue settles (scenery first, then each camera; cameras
    that disagree settle nothing)."""
    out: dict[str, SonarChoice] = {}
    rigs: dict = {}
    for cid in ambiguous:
        cands = np.asarray(detections[cid]["sonar"].get("two_candidates") or [], float).reshape(-1, 3)
        others = {o: sightings_sonar_m(d.get("sonar")) for o, d in detections.items() if o != cid and d.get("sonar")}
        k, why = choose_by_scenery(cands, others, radius_m)
        if k is None:
            k, why = by_images(cands, detections[cid], detections, cams, rigs)
        if k is not None:
            out[cid] = SonarChoice(cands[k], why)
    return out


def winner_and_losers_sonar_m(entry: dict | None) -> np.ndarray:
    """(K,3) a found entry's centre (row 0) and the ``other_candidates`` it beat; (0,3) when
    it found nothing or beat nothing."""
    if not usable_entry(entry) or entry.get("center") is None or not entry.get("other_candidates"):
        return np.zeros((0, 3))
    return np.asarray([entry["center"], *entry["other_candidates"]], float).reshape(-1, 3)


def reexamine_winners(detections: dict, cams: dict[str, CameraModel], radius_m: float,
                      found) -> dict[str, SonarChoice]:
    """{capture_id: choice} for the captures of ``found`` whose sonar entry chose a clear
    winner that the static-scenery cue says is scenery while one of the round objects it beat
    moves; a camera whose image cue singles out another candidate (the winner, say) vetoes."""
    out: dict[str, SonarChoice] = {}
    rigs: dict = {}
    for cid in found:
        cands = winner_and_losers_sonar_m(detections[cid].get("sonar"))
        if len(cands) < 2:
            continue
        others = {o: sightings_sonar_m(d.get("sonar")) for o, d in detections.items() if o != cid and d.get("sonar")}
        k, _ = choose_by_scenery(cands, others, radius_m)
        if not k:  # no choice, or the winner itself
            continue
        k_img, _ = by_images(cands, detections[cid], detections, cams, rigs)
        if k_img is not None and k_img != k:
            continue
        out[cid] = SonarChoice(cands[k], winner_phrase(int(seen_counts(cands[:1], others, radius_m)[0]), len(others)))
    return out


def by_images(cands: np.ndarray, capture: dict, detections: dict, cams: dict, rigs: dict) -> tuple[int | None, str]:
    """The image cue over every camera of one capture (``rigs`` caches the registrations)."""
    votes = {}
    for name, cam in cams.items():
        if name not in capture:
            continue
        if name not in rigs:
            rigs[name] = rig_registration(cam, detections, name)
        k = choose_by_image(cands, cam, rigs[name], capture.get(name))
        if k is not None:
            votes[name] = k
    if len(set(votes.values())) != 1:
        return None, ""
    name, k = next(iter(votes.items()))
    return k, image_phrase(name)
