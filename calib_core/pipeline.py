"""Session-level flow: files -> detections -> correspondences (pure functions).

The shells (CLI, workbench) call these so that they give the same numbers:
- :func:`detect_session` runs the detectors on every capture whose entry is missing or
  ``auto`` and merges the results (operator entries are never touched);
- :func:`refit_image` / :func:`refit_sonar` turn an operator's click or pick into a
  ``corrected`` entry (refit near the hint; the hint itself when the refit fails);
- :func:`correspondences` builds the solver's input for one camera.

One capture's detection (and :class:`SessionData`) lives in :mod:`calib_core.detect.entries`,
re-exported here; :mod:`calib_core.parallel` runs it in worker processes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from calib_core.detect.entries import (SessionData, as_data, beam_capture_ids, beam_crop_of,  # noqa: F401  (public API)
                                       beam_width_from_crops, detect_image_entry, detect_one, detect_sonar_entry,
                                       estimate_session_beam_width, session_beam_width)
from calib_core.detect.image.score import entry_logit
from calib_core.detect.reasons import range_is_measured
from calib_core.detections import is_operator_entry, merge_auto, now_iso
from calib_core.errors import SessionError
from calib_core.session import Session

Progress = Callable[[int, int, str], None]

# Uncertainty assumed for entries that carry no covariance (e.g. hand-corrected ones).
DEFAULT_SIGMA_IMAGE_PX = 1.0
DEFAULT_SIGMA_SONAR_M = 0.005
CLICK_SIGMA_IMAGE_PX = 2.0  # an operator's click without a successful refit
PICK_SIGMA_SONAR_M = 0.02  # an operator's pick without a successful refit


def pending(session: Session, detections: dict, captures=None, redetect_auto: bool = True) -> list[tuple[str, str]]:
    """(capture_id, sensor) pairs that need automatic detection (missing, or ``auto`` when
    ``redetect_auto``; fingerprints are not looked at here, see :func:`stale`)."""
    out = []
    for cap in session.captures:
        if captures is not None and cap.id not in captures:
            continue
        for sensor in ["sonar", *cap.image_paths]:
            e = detections.get(cap.id, {}).get(sensor)
            if e is None or (not is_operator_entry(e) and redetect_auto):
                out.append((cap.id, sensor))
    return out


def detection_inputs(data: SessionData, capture_id: str, sensor: str) -> tuple[list, dict]:
    """(input files, parameters) of one automatic detection: what its fingerprint covers."""
    s = data.session
    cap = s.capture(capture_id)
    if sensor == "sonar":
        return [cap.cloud_path], {"sensor": "sonar", "sphere_diameter_m": s.sphere_diameter_m,
                                  "beam_width_deg": round(float(data.effective_beam_width_deg), 4)}
    spec = s.cameras[sensor]
    paths = [cap.image_paths[sensor], spec.intrinsics_path] + ([spec.background_path] if spec.background_path else [])
    params = {"sensor": "image", "sphere_diameter_m": s.sphere_diameter_m,
              "background_window_s": list(spec.background_window_s)}
    if spec.intrinsics_entry is not None:  # which camera of a Kalibr camchain
        params["intrinsics_entry"] = spec.intrinsics_entry
    return paths, params


def stale(data: SessionData, detections: dict, todo: list[tuple[str, str]], strict: bool = False) -> list:
    """The pairs of ``todo`` whose entry is not an ``auto`` entry with a matching fingerprint."""
    from calib_core.fingerprint import matches

    out = []
    for cid, sensor in todo:
        paths, params = detection_inputs(data, cid, sensor)
        if not matches(detections.get(cid, {}).get(sensor), data.session.root, paths, params, strict=strict):
            out.append((cid, sensor))
    return out


def _with_fingerprint(data: SessionData, cid: str, sensor: str, entry: dict, hint: dict | None = None) -> dict:
    from calib_core.fingerprint import fingerprint

    paths, params = detection_inputs(data, cid, sensor)
    entry["fingerprint"] = fingerprint(data.session.root, paths, dict(params, **(hint or {})))
    entry["detected_at"] = now_iso()
    return entry


def detect_session(session_or_data, detections: dict, progress: Progress | None = None,
                   captures=None, redetect_auto: bool = True, estimate_beam_width: bool = True,
                   reuse: bool = True, workers: int | None = None) -> dict:
    """Detect every missing (and, by default, every ``auto``) entry; return merged detections.

    Entries an operator set (accepted / corrected / rejected) are returned unchanged. With
    ``reuse``, an ``auto`` entry whose fingerprint (:mod:`calib_core.fingerprint`) still matches
    is kept as it is. The sonar's effective beam width is estimated once per session (with
    ``estimate_beam_width`` and at least 3 clouds) and recorded in every sonar entry; later runs
    adopt the recorded width, so re-detection reproduces entries exactly. Detection runs in
    ``workers`` processes (default: the CPU count; see :mod:`calib_core.parallel`); the beam
    width estimate runs there too, alongside the image detections, which do not need it.
    """
    from calib_core.parallel import run_detections

    data = as_data(session_or_data)
    data.adopt_beam_width(detections)
    todo = pending(data.session, detections, captures, redetect_auto)
    sonar_ids = [cid for cid, sensor in todo if sensor == "sonar"]
    beam_ids = sonar_ids if estimate_beam_width and data.beam_width_deg is None and len(sonar_ids) >= 3 else []
    if reuse:  # with the beam width still to estimate, no sonar entry can match
        keep = set(stale(data, detections, [t for t in todo if not (beam_ids and t[1] == "sonar")]))
        todo = [t for t in todo if t in keep or (beam_ids and t[1] == "sonar")]
    if progress and beam_ids:
        progress(0, len(todo), "estimating the sonar's effective beam width")
    auto: dict = {}
    beam_dets = {cid: detections.get(cid, {}) for cid in beam_ids}
    for cid, sensor, entry in run_detections(data, todo, progress, workers, beam_ids, beam_dets):
        auto.setdefault(cid, {})[sensor] = _with_fingerprint(data, cid, sensor, entry)
    merged = merge_auto(detections, auto)
    for cid, entry in _resolve_ambiguous_sonar(data, merged, only=set(auto)).items():
        auto[cid]["sonar"] = entry
    merged = merge_auto(detections, auto)
    regs = _registrations(data, merged, set(auto))
    stereo = _stereo_predictions(data, merged, set(auto), regs)
    refusals = _stereo_refusals(data, merged, set(auto), stereo)
    for (cid, cam), entry in refusals.items():
        auto[cid][cam] = entry
    merged = merge_auto(detections, auto)
    if refusals:  # the refused centres leave the registrations: predict again without them
        regs = _registrations(data, merged, set(auto))
        stereo = _stereo_predictions(data, merged, set(auto), regs)
    for cam in data.session.cameras:
        # the first round's registration is the one the stereo predictions were made from (same
        # detections, same captures, a seeded RANSAC): computed once, not again
        for cid, entry in _resolve_ambiguous_images(data, merged, cam, set(auto), stereo.get(cam), regs.get(cam)).items():
            auto[cid][cam] = entry
    if progress:
        progress(len(todo), len(todo), "done")
    return merge_auto(detections, auto)


def _resolve_ambiguous_sonar(data: SessionData, detections: dict, only: set) -> dict:
    """Second look at the "two candidates" sonar entries (among captures in ``only``): the
    candidate that the static scenery or the images single out is refitted with the detector
    seeded there (see :mod:`calib_core.disambiguate.sonar`); kept only when the refit finds the
    sphere within a radius of it. {capture_id: new sonar entry}."""
    from calib_core.disambiguate.sonar_rounds import settle_sonar

    auto = [(cid, e) for cid in only if (e := detections.get(cid, {}).get("sonar")) and e.get("status") == "auto"]
    ambiguous = [cid for cid, e in auto if e.get("center") is None and e.get("two_candidates")]
    winners = [cid for cid, e in auto if e.get("center") is not None and e.get("other_candidates")]
    if not ambiguous and not winners and len(auto) < 4:  # (a look past scenery needs other captures)
        return {}
    r = data.session.sphere_radius_m
    cams = {name: data.camera(name) for name in data.session.cameras}
    plain = [cid for cid, e in auto if e.get("center") is not None]
    choices = settle_sonar(detections, cams, r, ambiguous, winners, plain)
    out = {}
    for cid, choice in choices.items():
        entry = detect_sonar_entry(data, cid, seed_center_m=choice.center_sonar_m)
        if entry.get("center") is not None and np.linalg.norm(np.asarray(entry["center"]) - choice.center_sonar_m) <= r:
            seed = [round(float(v), 4) for v in choice.center_sonar_m]
            old = detections[cid]["sonar"]
            cands = old.get("two_candidates") or [old["center"], *(old.get("other_candidates") or [])]
            entry.update(resolved_by=choice.resolved_by, seed_center_m=seed, two_candidates=cands)
            out[cid] = _with_fingerprint(data, cid, "sonar", entry, {"seed_center_m": seed})
    return out


def _resolve_ambiguous_images(data: SessionData, detections: dict, cam: str, only: set, stereo=None,
                              registration=None) -> dict:
    """Second look at camera ``cam``'s images (among captures in ``only``) guided by the sonar.

    "two candidates" images are refitted at the candidate the sonar's centres single out, and
    images whose detection does not fit the rough rig registration are refitted where the
    registration says the sphere must be (see :mod:`calib_core.disambiguate.image`). A refit is kept
    only when the detector finds the sphere there; failing that, when the registration is well
    supported, an outline of the predicted size is looked for at the predicted place
    (:mod:`calib_core.detect.image.predicted`: half an outline is enough) and kept when it agrees
    with the registration. When that fails too, the entry says why.

    When a look at a predicted place found the sphere and other images are still without one, a
    second round refits the registration with the new centres and looks again at those (at most
    2 rounds): a registration on 3 plain detections only predicts well near its checks.

    ``stereo``: {capture: StereoPrediction} from another camera's registration carried by the stereo
    transform (:func:`_stereo_predictions`): where this camera's own registration cannot predict a
    capture it has no centre for, the look goes there.

    ``registration``: this camera's :func:`_camera_registration` on exactly these ``detections``
    and ``only``, when the caller has it already (used by the first round only).
    """
    out = _resolve_round(data, detections, cam, only, stereo, registration)
    found = any(e.get("center") is not None and "predicted place" in (e.get("resolved_by") or "") for e in out.values())
    rest = {cid for cid in only if (out.get(cid) or detections.get(cid, {}).get(cam) or {}).get("center") is None}
    if not found or not rest:
        return out
    merged = merge_auto(detections, {cid: {cam: e} for cid, e in out.items()})
    out.update(_resolve_round(data, merged, cam, rest, stereo))
    return out


def _camera_registration(data: SessionData, detections: dict, cam: str, only: set):
    """(Resolution, {capture: candidates}, [missing captures]) of camera ``cam``'s rough
    registration to the sonar (:func:`calib_core.disambiguate.image.resolve_candidates`)."""
    from calib_core.disambiguate.image import resolve_candidates

    centers, cands, missing = _registration_inputs(detections, cam, only)
    range_free = [c for c in cands if not range_is_measured(detections[c][cam])]
    res = resolve_candidates(data.camera(cam), centers, cands, predict_for=missing,
                             rough=[c for c in missing if c in cands], range_free=range_free)
    return res, cands, missing


def _resolve_round(data: SessionData, detections: dict, cam: str, only: set, stereo=None, registration=None) -> dict:
    """One round of :func:`_resolve_ambiguous_images`: {capture_id: new entry}."""
    _, cands, missing = _registration_inputs(detections, cam, only)
    if not any(cid in only for cid in cands) and not missing:
        return {}
    model = data.camera(cam)
    res, cands, missing = registration or _camera_registration(data, detections, cam, only)
    out = _looks_on_three(data, detections, cam, only, cands, missing) if res.T_cam_sonar is None else {}
    for cid, ((u, v, rng_m), why) in _looks(res, cands, missing, detections, cam, only).items():
        radius_px = model.fx * data.session.sphere_radius_m / max(rng_m, 1e-6)
        entry = detect_image_entry(data, cid, cam, hint_uv_px=(u, v), hint_radius_px=radius_px)
        hint = {"hint_uv_px": [round(float(u), 3), round(float(v), 3)], "hint_radius_px": round(float(radius_px), 3)}
        refit = (entry.get("center") is not None and np.hypot(entry["center"][0] - u, entry["center"][1] - v) < 0.5 * radius_px
                 and _range_agrees(entry.get("range_m"), rng_m))
        if cid in res.predicted_uvr and _trusted(res, len(cands), cid) and not (refit and _clear_refit(entry)):
            # a well supported registration knows the size too: the look at the predicted place and
            # size beats a faint free refit (which may have taken a larger outline around it)
            looked = _look_at_prediction(data, cid, cam, (u, v, rng_m), (_scatter_px(res, cid), _registration_phrase(res)),
                                         detections[cid][cam], hint)
            if looked is not None and (looked.get("center") is not None or not refit):
                out[cid] = looked
                continue
        if refit:
            entry["resolved_by"] = why
            out[cid] = _with_fingerprint(data, cid, cam, entry, hint)
    own = {cid for cid in res.predicted_uvr if _trusted(res, len(cands), cid)}
    for cid, p in (stereo or {}).items():
        if cid in missing and cid not in out and cid not in own and detections[cid][cam].get("status") == "auto":
            out[cid] = _look_at_stereo(data, cid, cam, p, detections[cid][cam])
    return {cid: e for cid, e in out.items() if e is not None}


def _looks_on_three(data: SessionData, detections: dict, cam: str, only: set, cands: dict, missing: list) -> dict:
    """{capture: entry} of the looks at the places a registration on exactly 3 plain detections
    predicts (:func:`calib_core.disambiguate.three.register_on_three`), when at least
    PREDICTION_MIN_CHECKS of them find the sphere; else {}.

    Such a registration cannot check itself, so its looks are its checks: a look counts only where
    the registration's expected error is at most CHECKED_MAX_ERROR_PX (its sensitivity to a 1.5 %
    range error of one plain detection), with a window that size, and only when it finds an outline
    of the predicted size (its range agrees) within CHECK_MAX_PX of the predicted place. A wrong
    registration predicts places where no such outline is; a look that finds nothing keeps the
    capture's first entry. The kept looks then join the plain detections in the next round
    (:func:`_resolve_ambiguous_images`), whose registration on 5 or more predicts the rest."""
    from calib_core.disambiguate.three import register_on_three

    plain = [c for c, k in cands.items() if len(k) == 1 and c not in missing and range_is_measured(detections[c][cam])]
    todo = [c for c in missing if c in only and detections[c][cam].get("status") == "auto"]
    if len(plain) != 3 or len(todo) < PREDICTION_MIN_CHECKS:
        return {}
    centers = _sonar_centers(detections)
    res = register_on_three(data.camera(cam), centers, cands, plain, todo)
    if res is None:
        return {}
    found = {}
    for cid, (u, v, rng_m) in res.predicted_uvr.items():
        sigma = res.sigma_px.get(cid, float("inf"))
        if not sigma <= CHECKED_MAX_ERROR_PX:
            continue
        radius_px = data.camera(cam).fx * data.session.sphere_radius_m / max(rng_m, 1e-6)
        hint = {"hint_uv_px": [round(float(u), 3), round(float(v), 3)], "hint_radius_px": round(float(radius_px), 3)}
        entry = _look_at_prediction(data, cid, cam, (u, v, rng_m), (max(res.residual_px, sigma), ""), detections[cid][cam], hint)
        if entry is not None and entry.get("center") is not None and np.hypot(entry["center"][0] - u, entry["center"][1] - v) <= CHECK_MAX_PX:
            found[cid] = entry
    if len(found) < PREDICTION_MIN_CHECKS:
        return {}
    phrase = (f"registration on 3 captures, {res.residual_px:.1f} px, confirmed by {len(found)} looks at its predictions "
              f"within {CHECK_MAX_PX:.0f} px")
    for entry in found.values():
        entry["resolved_by"] = f"sonar-guided second look at the predicted place and size ({phrase})"
    return found


def _look_at_stereo(data: SessionData, cid: str, cam: str, p, first: dict) -> dict | None:
    """The look at the place and size another camera's registration, carried by the stereo
    transform, predicts (``p``: a StereoPrediction); its window follows the prediction's stated
    uncertainty (RMS distance = sigma x sqrt 2)."""
    radius_px = data.camera(cam).fx * data.session.sphere_radius_m / max(p.range_m, 1e-6)
    hint = {"hint_uv_px": [round(float(x), 3) for x in p.uv_px], "hint_radius_px": round(float(radius_px), 3)}
    phrase = f"camera {p.source}'s registration carried by the stereo transform, {p.sigma_px:.1f} px"
    return _look_at_prediction(data, cid, cam, (*p.uv_px, p.range_m), (np.sqrt(2.0) * p.sigma_px, phrase), first, hint)


def _looks(res, cands: dict, missing: list, detections: dict, cam: str, only: set) -> dict:
    """{capture_id: ((u, v, range_m), why)}: the places to look again at."""
    looks = {cid: (tuple(cands[cid][k]), "sonar consistency: the other candidates do not fit one rig transform")
             for cid, k in res.chosen.items()}
    for cid, uvr in res.predicted_uvr.items():
        if cid in only and detections[cid][cam].get("status") == "auto":
            looks[cid] = (uvr, f"sonar-guided second look: the first detection {_first_outcome(cid, cands, missing)}")
    return looks


def _first_outcome(cid: str, cands: dict, missing: list) -> str:
    """What the first detection of a capture the registration sends back to look again saw."""
    if cid in missing:
        return "found only a partly hidden outline" if cid in cands else "found nothing"
    if len(cands.get(cid, ())) > 1:
        return "saw two round objects, and the registration could not tell them apart"
    return "did not fit the rig transform"


def _registration_inputs(detections: dict, cam: str, only: set) -> tuple[dict, dict, list]:
    """({capture: sonar centre}, {capture: (K,3) image candidates (u, v, range)}, [captures in
    ``only`` whose image found nothing]) for the registration of camera ``cam``."""
    centers, cands, missing = {}, {}, []
    for cid, d in detections.items():
        son, img = d.get("sonar"), d.get(cam)
        if not son or son.get("status") == "rejected" or son.get("center") is None or not img:
            continue
        if img.get("center") is not None and img.get("range_m") and img.get("status") != "rejected":
            cands[cid] = np.array([[*img["center"], img["range_m"]]], float)
        elif img.get("two_candidates") and cid in only and img.get("status") == "auto":
            cands[cid] = np.asarray(img["two_candidates"], float).reshape(-1, 3)
        elif img.get("center") is None and cid in only and img.get("status") == "auto":
            missing.append(cid)
            if img.get("partial_center_uv_px") and img.get("partial_range_m"):  # a partly hidden outline
                cands[cid] = np.array([[*img["partial_center_uv_px"], img["partial_range_m"]]], float)
        else:
            continue
        centers[cid] = np.asarray(son["center"], float)
    return centers, cands, missing


def _well_registered(res, n_with_candidates: int) -> bool:
    """A registration on at least PREDICTION_MIN_SUPPORT plain detections that most captures agree
    with (the first test of :func:`_trusted`)."""
    return (res.T_cam_sonar is not None and np.isfinite(res.residual_px) and not res.range_rel_rms > PREDICTION_MAX_RANGE_RMS
            and res.support >= PREDICTION_MIN_SUPPORT and res.support + res.rough_agree >= 0.6 * n_with_candidates)


def _stereo_source(regs: dict, b: str, stereo: dict, cameras) -> str | None:
    """The camera whose registration, carried by the stereo transforms, predicts camera ``b``'s
    centres: well registered, tied to ``b`` by a stated stereo transform or a chain of them
    (:mod:`calib_core.stereo.chain`), and better registered than ``b`` (more plain detections agree
    with it; then the smaller scatter)."""
    from calib_core.stereo.chain import stereo_path

    def key(c):
        return (regs[c][0].support, -regs[c][0].residual_px)

    cands = [a for a in regs if a != b and stereo_path(stereo, a, b, cameras) is not None and _well_registered(*regs[a])]
    best = max(cands, key=key, default=None)
    if best is None or (_well_registered(*regs[b]) and key(best) <= key(b)):
        return None
    return best


def _sonar_centers(detections: dict) -> dict:
    """{capture: sonar centre} of the captures whose sonar entry has one (not rejected)."""
    return {cid: np.asarray(d["sonar"]["center"], float) for cid, d in detections.items()
            if d.get("sonar") and d["sonar"].get("status") != "rejected" and d["sonar"].get("center") is not None}


def _registrations(data: SessionData, detections: dict, only: set) -> dict:
    """{camera: :func:`_camera_registration`} for the stereo predictions; empty when the session
    has no stereo transform, one camera, or nothing detected afresh (no capture to predict for)."""
    cams = list(data.session.cameras)
    if not data.session.stereo or len(cams) < 2 or not only:
        return {}
    return {c: _camera_registration(data, detections, c, only) for c in cams}


def _stereo_predictions(data: SessionData, detections: dict, only: set, full: dict | None = None) -> dict:
    """{camera b: {capture: StereoPrediction}} from the best registered other camera tied to ``b``
    by the stereo transforms, chained when the session ties both only to a third camera
    (:mod:`calib_core.stereo.vouch`, :mod:`calib_core.stereo.chain`); empty without a stereo transform.
    ``full``: :func:`_registrations` of these ``detections`` and ``only`` when the caller has them."""
    from calib_core.solve.stereo_cov import key_stereo_cov
    from calib_core.stereo.chain import chained_stereo
    from calib_core.stereo.vouch import stereo_predictions

    stereo, cams = data.session.stereo, list(data.session.cameras)
    full = _registrations(data, detections, only) if full is None else full
    if not full:
        return {}
    regs = {c: (res, len(cands)) for c, (res, cands, _) in full.items()}
    out = {}
    for b in cams:
        a = _stereo_source(regs, b, stereo, cams)
        if a is None:
            continue
        T_b_a, cov, _ = chained_stereo(stereo, lambda k: key_stereo_cov(data.session, k)[0], a, b, cams)
        res_a = regs[a][0]
        out[b] = stereo_predictions(data.camera(b), T_b_a, cov, res_a.T_cam_sonar, res_a.residual_px,
                                    data.camera(a).fx, _sonar_centers(detections), a,
                                    _support_centers(data.camera(a), detections, a, *full[a][:2]))
    return out


def _support_centers(model, detections: dict, cam: str, res, cands: dict) -> np.ndarray:
    """(N,3) the sonar centres of camera ``cam``'s plain detections that its registration ``res``
    rests on: one candidate, a measured centre, within 3 x its scatter (at least 3 px) of its projection."""
    T, tol = res.T_cam_sonar, max(3.0, 3.0 * res.residual_px)
    out = []
    for cid, k in cands.items():
        e = detections[cid][cam]
        if len(k) != 1 or e.get("center") is None:
            continue
        X = np.asarray(detections[cid]["sonar"]["center"], float)
        uv = model.project((T[:3, :3] @ X + T[:3, 3])[None])[0]
        if np.hypot(*(uv - np.asarray(e["center"], float))) <= tol:
            out.append(X)
    return np.asarray(out, float).reshape(-1, 3)


def _stereo_refusals(data: SessionData, detections: dict, only: set, stereo: dict | None = None) -> dict:
    """{(capture, camera): entry without a centre} for the plain automatic detections (among
    captures in ``only``) that another camera's registration, carried by the stereo transform
    (``stereo``: :func:`_stereo_predictions` of these detections, computed when not given), refuses
    (:func:`calib_core.stereo.vouch.refused`). The refused centre is kept in the entry."""
    from calib_core.detect.reasons import stereo_refusal_reason
    from calib_core.stereo.vouch import refused

    out = {}
    if stereo is None:
        stereo = _stereo_predictions(data, detections, only)
    for cam, preds in stereo.items():
        for cid, p in preds.items():
            e = detections.get(cid, {}).get(cam)
            if (cid not in only or not e or e.get("status") != "auto" or e.get("center") is None
                    or not refused(p, e["center"], e.get("cov_px2"))):
                continue
            off = float(np.hypot(*(np.asarray(e["center"], float) - p.uv_px)))
            new = {k: v for k, v in e.items() if k not in ("center", "cov_px2", "range_m", "range_sigma_m")}
            new.update(reason=stereo_refusal_reason(off, p.source), refused_center=e["center"],
                       stereo_predicted_uv_px=[round(float(x), 2) for x in p.uv_px])
            out[(cid, cam)] = new
    return out


# A look at the predicted place and size needs a registration that most plain detections agree
# with (a wrong one puts the look on clutter, where only the null test of
# calib_core.detect.image.predicted stands between brick and a "sphere"), at least this many
PREDICTION_MIN_SUPPORT = 4
# ... and whose ranges agree with the images' ranges (from the apparent size) to this RMS: the
# look takes the predicted size as known to a few per cent (image.predicted.PRIOR_REL_SIGMA); with
# a size 8 % off it finds some balls 3-4 px off (bench_predicted_look.py)
PREDICTION_MAX_RANGE_RMS = 0.04


# a free refit is kept over the look at the predicted size when the score model's logistic gives it
# even odds or more before any calibration (a threshold set on that scale: recalibrations of the
# score leave the decision alone); an entry that records no outline features, when its score is
# at least CLEAR_SCORE (the same threshold through the first round's Platt line)
CLEAR_LOGIT = 0.0
CLEAR_SCORE = 0.7831


def _clear_refit(entry: dict) -> bool:
    """Whether a free refit is clear enough to keep over the look (CLEAR_LOGIT / CLEAR_SCORE)."""
    z = entry_logit(entry)
    return z >= CLEAR_LOGIT if z is not None else entry.get("score", 0) >= CLEAR_SCORE


def _range_agrees(range_m, predicted_m: float) -> bool:
    """The image's range (from the apparent size) within the registration's tolerance."""
    return range_m is not None and abs(float(range_m) - predicted_m) <= 0.05 * predicted_m + 0.03


def _trusted(res, n_with_candidates: int, cid: str) -> bool:
    """The registration agrees with enough plain detections to predict where capture ``cid``'s
    sphere is: at least PREDICTION_MIN_SUPPORT, or exactly 3 confirmed by partly hidden outlines
    (:func:`_checked`) when its expected error there is small (:func:`_expected_error_px`); and,
    with the partly hidden outlines that agree with it, with 60 % of the captures with candidates
    (an outline that agrees counts for it, not only against it: lidar-chair s45's second round had
    4 plain detections and 3 agreeing outlines of 7, and 4 < 0.6 x 7 refused it)."""
    if res.T_cam_sonar is None or not np.isfinite(res.residual_px) or res.range_rel_rms > PREDICTION_MAX_RANGE_RMS:
        return False
    if res.support >= PREDICTION_MIN_SUPPORT and res.support + res.rough_agree >= 0.6 * n_with_candidates:
        return True
    return (res.support == 3 and _checked(res) and res.support + len(_confirming(res)) >= 0.6 * n_with_candidates
            and _expected_error_px(res, cid) <= CHECKED_MAX_ERROR_PX)


# A registration on exactly 3 plain detections (no redundancy of its own, see
# disambiguate._checked_on_three) is trusted when at least this many partly hidden outlines, which
# it was not fitted on, agree with it in 3D (the RANSAC tolerance) ...
PREDICTION_MIN_CHECKS = 2
# ... and in the image, each outline's centre within this many px of the registration's projection
# (a partly hidden outline's own centre is a few px off: a bound, not a measure) ...
CHECK_MAX_PX = 10.0
# ... and only for the captures where its expected error (:func:`_expected_error_px`) is at most
# this: bench_predicted_look.py finds no ball > 3 px off with a prediction 3 px off, but 4 of 60
# 3.6-3.8 px off with one 6 px off (and the size 8 % off)
CHECKED_MAX_ERROR_PX = 4.0


def _confirming(res) -> dict:
    """{capture: px} the checks within CHECK_MAX_PX of the 3-point registration's projection."""
    return {c: d for c, d in res.checks_px.items() if d <= CHECK_MAX_PX}


def _refuting(res) -> dict:
    """{capture: px} the checks that contradict the 3-point registration: farther than CHECK_MAX_PX
    and farther than its own uncertainty there (``res.sigma_px``, a 1.5 % range error of one plain
    detection). A check beyond CHECK_MAX_PX but within that sigma neither confirms nor refutes: the
    registration is not known to 10 px there (far from its 3 points, long lever arms), so an outline
    11 px off says nothing (lidar-chair s45 p07: a partly hidden outline 0.3 px from the truth, 11 px
    from a prediction whose sigma there is 116 px, made the registration untrusted everywhere)."""
    return {c: d for c, d in res.checks_px.items() if d > CHECK_MAX_PX and not d <= res.sigma_px.get(c, 0.0)}


def _checked(res) -> bool:
    """At least PREDICTION_MIN_CHECKS partly hidden outlines confirm a 3-point registration and
    none refutes it (:func:`_confirming`, :func:`_refuting`)."""
    return (len(_confirming(res)) >= PREDICTION_MIN_CHECKS and not _refuting(res)
            and all(np.isfinite(res.sigma_px.get(c, np.inf)) and res.sigma_px[c] > 0 for c in res.checks_px))


def _expected_error_px(res, cid: str) -> float:
    """A 3-point registration's expected prediction error at capture ``cid`` (px): its sensitivity
    there to the plain detections' ranges (``res.sigma_px``), scaled by how far off the checks
    actually are for their sensitivity (RMS of check / sigma; it includes the outlines' own
    error, so it errs on the large side). Far from the checks (long lever arms) it grows."""
    checks = _confirming(res)
    if not checks:
        return float("inf")
    ratio = float(np.sqrt(np.mean([(d / res.sigma_px[c]) ** 2 for c, d in checks.items()])))
    return ratio * res.sigma_px.get(cid, float("inf"))


def _registration_phrase(res) -> str:
    """"registration on N captures, X px" (and its checks, for a 3-point registration)."""
    text = f"registration on {res.support} captures, {res.residual_px:.1f} px"
    if res.support < PREDICTION_MIN_SUPPORT and res.checks_px:
        checks = _confirming(res) or res.checks_px
        text += f", checked by {len(checks)} partly hidden outlines within {max(checks.values()):.1f} px"
    return text


def _scatter_px(res, cid: str) -> float:
    """How far off the prediction at capture ``cid`` may be: the plain detections' RMS, or, for a
    3-point registration (which fits its own 3 points too well to tell), its expected error there."""
    if res.support >= PREDICTION_MIN_SUPPORT or not res.checks_px:
        return res.residual_px
    return max(res.residual_px, _expected_error_px(res, cid))


def _look_at_prediction(data: SessionData, cid: str, cam: str, uvr, why: tuple, first: dict, hint: dict) -> dict | None:
    """The entry from an outline of the predicted size at the predicted place (found, kept when
    its range agrees with the registration), or the first entry with the reason it still failed.
    ``why``: (how far off the prediction may be, px; the phrase naming the registration)."""
    scatter_px, phrase = why
    from calib_core.detect.image.predicted import detect_at_prediction
    from calib_core.io.images import load_image

    u, v, rng_m = uvr
    model = data.camera(cam)
    radius_px = model.fx * data.session.sphere_radius_m / max(rng_m, 1e-6)
    # the window: a few times the registration's own scatter on the plain detections (partly
    # hidden outlines take part in the consensus only: their centres and ranges are rough)
    shift_frac = float(np.clip(3.0 * scatter_px, 3.0, 0.3 * radius_px) / radius_px)
    image = load_image(data.session.capture(cid).image_paths[cam], (model.width_px, model.height_px))
    det = detect_at_prediction(image, model, data.session.sphere_radius_m, (u, v), radius_px,
                               background=data.background(cam), shift_frac=shift_frac)
    if det.found and _range_agrees(det.range_m, rng_m):
        entry = det.to_entry()
        entry["resolved_by"] = f"sonar-guided second look at the predicted place and size ({phrase})"
        return _with_fingerprint(data, cid, cam, entry, hint)
    if first.get("center") is not None:
        return None  # a detection that does not fit the registration stays for the solver to judge
    entry = dict(first)
    # a failed look reused from an earlier run already carries the first detection's own reason
    entry["first_reason"] = first.get("first_reason") or first.get("reason")
    entry["reason"] = det.reason if not det.found else f"outline at the predicted place but at another range: {det.range_m:.2f} m"
    return entry


def refit_image(session_or_data, capture_id: str, cam: str, hint_uv_px, hint_radius_px=None) -> dict:
    """An operator clicked the sphere centre at ``hint_uv_px`` (raw px): refit near it.

    Returns a ``corrected`` entry: the refit when it succeeds near the click, else the click
    itself with a larger uncertainty.
    """
    hint = np.asarray(hint_uv_px, float).reshape(2)
    entry = detect_image_entry(session_or_data, capture_id, cam, hint_uv_px=hint, hint_radius_px=hint_radius_px)
    tol = max(10.0, 0.5 * float(hint_radius_px or 0.0))
    if "center" in entry and np.linalg.norm(np.asarray(entry["center"]) - hint) <= tol:
        entry.update(status="corrected", hint_uv_px=[float(v) for v in hint], refit=True)
        return entry
    s2 = CLICK_SIGMA_IMAGE_PX**2
    out = {"status": "corrected", "center": [float(v) for v in hint], "cov_px2": [s2, 0.0, 0.0, s2],
           "method": "operator-click", "refit": False}
    if hint_radius_px:
        out["radius_px"] = float(hint_radius_px)
    if entry.get("reason"):
        out["refit_reason"] = entry["reason"]
    return out


def refit_sonar(session_or_data, capture_id: str, seed_center_m) -> dict:
    """An operator picked/dragged the sphere centre to ``seed_center_m`` (sonar frame): refit near it."""
    seed = np.asarray(seed_center_m, float).reshape(3)
    data = as_data(session_or_data)
    entry = detect_sonar_entry(data, capture_id, seed_center_m=seed)
    if "center" in entry and np.linalg.norm(np.asarray(entry["center"]) - seed) <= 2.0 * data.session.sphere_diameter_m:
        entry.update(status="corrected", seed_center_m=[float(v) for v in seed], refit=True)
        return entry
    s2 = PICK_SIGMA_SONAR_M**2
    out = {"status": "corrected", "center": [float(v) for v in seed], "method": "operator-pick", "refit": False,
           "cov_m2": [s2, 0, 0, 0, s2, 0, 0, 0, s2]}
    if entry.get("reason"):
        out["refit_reason"] = entry["reason"]
    return out


@dataclass(frozen=True)
class Correspondences:
    """Sphere centres seen by the sonar and one camera, one row per usable capture.

    Attributes:
        capture_ids: capture ids, in manifest order.
        uv_px: (N,2) raw pixel centres (perspective projection of the sphere centre).
        cov_uv_px2: (N,2,2) their covariances (px^2).
        X_sonar_m: (N,3) sphere centres in the sonar frame (m).
        cov_X_m2: (N,3,3) their covariances (m^2).
        statuses: (image status, sonar status) per row.
        skipped: {capture_id: reason} for captures not used.
        range_m, range_sigma_m: (N,) the image detection's camera-to-centre range (m, from the known
            diameter) and its 1-sigma; NaN where the entry has none (e.g. a click) or where its size
            was pulled towards the sonar's prediction (a look at the predicted place).
    """

    capture_ids: list[str]
    uv_px: np.ndarray
    cov_uv_px2: np.ndarray
    X_sonar_m: np.ndarray
    cov_X_m2: np.ndarray
    statuses: list[tuple[str, str]]
    skipped: dict[str, str]
    range_m: np.ndarray | None = None  # (N,) camera range from the sphere's apparent size, NaN if none
    range_sigma_m: np.ndarray | None = None  # (N,) its 1-sigma, NaN if none

    def __len__(self) -> int:
        return len(self.capture_ids)


def _cov(entry: dict, key: str, dim: int, sigma: float) -> np.ndarray:
    c = entry.get(key)
    if c is not None:
        C = np.asarray(c, float).reshape(dim, dim)
        if np.isfinite(C).all() and np.all(np.linalg.eigvalsh(0.5 * (C + C.T)) > 0):
            return 0.5 * (C + C.T)
    return np.eye(dim) * sigma**2


def correspondences(session: Session, detections: dict, cam: str) -> Correspondences:
    """Pair each capture's sonar centre with camera ``cam``'s image centre.

    Rejected entries and entries without a centre are skipped (with the reason in ``skipped``).
    """
    if cam not in session.cameras:
        raise SessionError(session.manifest_path, f"no camera '{cam}'")
    ids, uv, cuv, X, cX, st, skipped, rng = [], [], [], [], [], [], {}, []
    for cap in session.captures:
        if cam not in cap.image_paths:
            continue
        d = detections.get(cap.id, {})
        img, son = d.get(cam), d.get("sonar")
        why = None
        for name, e in (("image", img), ("sonar", son)):
            if why is None:
                if e is None:
                    why = f"no {name} detection"
                elif e.get("status") == "rejected":
                    why = f"{name} rejected"
                elif e.get("center") is None:
                    why = f"{name}: {e.get('reason') or 'not found'}"
        if why:
            skipped[cap.id] = why
            continue
        ids.append(cap.id)
        uv.append(img["center"])
        cuv.append(_cov(img, "cov_px2", 2, DEFAULT_SIGMA_IMAGE_PX))
        X.append(son["center"])
        cX.append(_cov(son, "cov_m2", 3, DEFAULT_SIGMA_SONAR_M))
        st.append((img["status"], son["status"]))
        # a range pulled towards the sonar-predicted size would pull the apparent-size scale to 1
        rng.append([_number(img.get("range_m")), _number(img.get("range_sigma_m"))] if range_is_measured(img)
                   else [float("nan")] * 2)
    return Correspondences(ids, np.asarray(uv, float).reshape(-1, 2), np.asarray(cuv, float).reshape(-1, 2, 2),
                           np.asarray(X, float).reshape(-1, 3), np.asarray(cX, float).reshape(-1, 3, 3), st, skipped,
                           np.asarray(rng, float).reshape(-1, 2)[:, 0], np.asarray(rng, float).reshape(-1, 2)[:, 1])


def _number(v) -> float:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else float("nan")
