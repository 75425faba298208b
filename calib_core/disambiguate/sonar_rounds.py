"""The session's sonar choices in two rounds, and a look past a round object that is scenery.

Round 1 is :mod:`calib_core.disambiguate.sonar` as it stands: each "two candidates" cloud is
settled by the static scenery or by the images, and each clear winner re-examined. But the image
cue needs a rough rig registration on captures whose sonar AND image entries are both plain,
and where scenery of the sphere's size lies in the sonar's view (round boulders on the seabed)
most clouds start out ambiguous: the registration has too few captures in round 1. Round 2
takes the captures round 1 settled as plain and tries again:

- the image cue for the "two candidates" clouds still open (e.g. a third candidate, a boulder
  seen in no other cloud, kept the scenery cue from deciding);
- a look past scenery (:func:`past_scenery`): a plain sonar detection whose centre sits where
  a round object of the sphere's size is seen in most other captures (SCENERY_WINNER_SHARE; the
  target is moved between captures, scenery is not), while every camera's image detection,
  through the registration, puts the sphere clearly elsewhere: the sonar is looked at again
  where the cameras put it (the caller refits there and keeps the refit only when it finds
  the sphere within a radius of that place).
"""

from __future__ import annotations

import numpy as np

from calib_core.camera import CameraModel
from calib_core.disambiguate.image import candidate_points_cam_m
from calib_core.disambiguate.sonar import (MIN_OTHERS, SonarChoice, by_images, usable_entry, choose_sonar_candidates,
                                          reexamine_winners, rig_registration, seen_counts, sightings_sonar_m)

# a plain sonar centre seen (within a sphere radius) in at least this share of the other
# captures is scenery, not the target (the target is moved between captures)
SCENERY_WINNER_SHARE = 0.5


def past_scenery_phrase(n_seen: int, n_others: int, cams) -> str:
    """The ``resolved_by`` text of a look past a scenery winner."""
    return (f"static scenery: the round object first found sits where one of the sphere's size is seen in "
            f"{n_seen} of {n_others} other captures; looked again where {_cameras(cams)} put the sphere")


def _cameras(cams) -> str:
    return f"camera {cams[0]}" if len(cams) == 1 else f"cameras {' and '.join(cams)}"


def settle_sonar(detections: dict, cams: dict[str, CameraModel], radius_m: float, ambiguous, winners,
                 plain) -> dict[str, SonarChoice]:
    """{capture: choice} over both rounds (see the module doc). ``ambiguous``: captures whose sonar
    entry records two candidates; ``winners``: found with ``other_candidates``; ``plain``: found."""
    out = choose_sonar_candidates(detections, cams, radius_m, ambiguous)
    out.update(reexamine_winners(detections, cams, radius_m, winners))
    settled = _with_choices(detections, out)
    rigs: dict = {}
    for cid in [c for c in ambiguous if c not in out]:
        cands = np.asarray(detections[cid]["sonar"].get("two_candidates") or [], float).reshape(-1, 3)
        k, why = by_images(cands, settled[cid], settled, cams, rigs)
        if k is not None:
            out[cid] = SonarChoice(cands[k], why)
    out.update(past_scenery(settled, cams, radius_m, [c for c in plain if c not in out], rigs))
    return out


def _with_choices(detections: dict, choices: dict) -> dict:
    """The detections with each chosen candidate as its capture's sonar centre (the candidates it
    records stay: they are sightings of the scenery)."""
    out = dict(detections)
    for cid, ch in choices.items():
        son = dict(detections[cid]["sonar"])
        son["center"] = [float(v) for v in ch.center_sonar_m]
        out[cid] = {**detections[cid], "sonar": son}
    return out


def past_scenery(detections: dict, cams: dict[str, CameraModel], radius_m: float, plain, rigs=None) -> dict:
    """{capture: choice at the place the cameras put the sphere} for the plain sonar detections
    of ``plain`` that are scenery and that every camera with a registration and a detection puts
    clearly elsewhere (cameras that disagree with one another decide nothing)."""
    rigs = {} if rigs is None else rigs
    out = {}
    for cid in plain:
        son = detections[cid].get("sonar")
        if not usable_entry(son) or son.get("center") is None:
            continue
        others = {o: sightings_sonar_m(d.get("sonar")) for o, d in detections.items() if o != cid and d.get("sonar")}
        n = len(others)
        seen = int(seen_counts(np.asarray([son["center"]], float), others, radius_m)[0])
        if n < MIN_OTHERS or seen < max(MIN_OTHERS, SCENERY_WINNER_SHARE * n):
            continue
        places = _camera_places(detections, cams, rigs, cid, np.asarray(son["center"], float))
        if not places or len(places) < sum(1 for c in cams if usable_entry(detections[cid].get(c))
                                           and detections[cid][c].get("center") is not None):
            continue  # a camera that sees the sphere on the winner (or cannot say) vetoes
        pts = np.array([p for p, _ in places.values()])
        tol = max(t for _, t in places.values())
        if np.max(np.linalg.norm(pts - pts.mean(axis=0), axis=1)) > tol:
            continue
        out[cid] = SonarChoice(pts.mean(axis=0), past_scenery_phrase(seen, n, sorted(places)))
    return out


def _camera_places(detections: dict, cams: dict, rigs: dict, cid: str, winner_sonar_m: np.ndarray) -> dict:
    """{camera: (sonar-frame point its image detection puts the sphere at, its tolerance in m)} for
    the cameras whose registration puts the winner more than twice that tolerance away."""
    out = {}
    for name, cam in cams.items():
        img = detections[cid].get(name)
        if not usable_entry(img) or img.get("center") is None or not img.get("range_m"):
            continue
        if name not in rigs:
            rigs[name] = rig_registration(cam, detections, name)
        T = rigs[name]
        if T is None:
            continue
        rng_m = float(img["range_m"])
        P_cam = candidate_points_cam_m(cam, np.array([[*img["center"], rng_m]]))[0]
        tol = 0.05 * rng_m + 0.03  # the loose gate of calib_core.disambiguate.image
        if np.linalg.norm(T[:3, :3] @ winner_sonar_m + T[:3, 3] - P_cam) <= 2 * tol:
            continue
        out[name] = (T[:3, :3].T @ (P_cam - T[:3, 3]), tol)
    return out
