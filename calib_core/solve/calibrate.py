"""Whole-session calibration: detections -> per-camera and joint solves -> calibration.json content.

:func:`calibrate_session` is what ``sonarcal calibrate`` and the workbench call. Operator
entries in detections.yaml (accepted / corrected) are used exactly as written, rejected ones
are left out, and the rest are detected afresh by :func:`calib_core.pipeline.detect_session`
(unless ``options.detect`` is False, when ``auto`` entries are used as they are).

Frames in the result: ``T_cam_sonar`` maps *true* sonar-frame points to the camera; when a
range scale ``s`` was estimated, cloud points must be divided by ``s`` first
(``X_true = X_cloud / s``). With ``s`` fixed at 1 (the default) cloud points map directly.
"""

from __future__ import annotations

import datetime as _dt
import math
from dataclasses import asdict, dataclass

import numpy as np

from calib_core import __version__
from calib_core.errors import SessionError
from calib_core.results import CALIBRATION_FORMAT
from calib_core.solve.consistency import consistency, consistency_phrase, is_warning
from calib_core.solve.stated import camera_data_from
from calib_core.solve.refine import ROBUST_LOSSES, Link
from calib_core.solve.scale import (diameter_sigma, outline_sigma_px, range_model, range_rel_sigma, size_route_caution,
                                   stereo_limit_note)
from calib_core.solve.shared_scale import shared_scale
from calib_core.solve.rig import find_stereo, solve_rig, table_i
from calib_core.solve.stereo_cov import assumed_stereo_text, stereo_link
from calib_core.solve.stereo_factor import stereo_factor_phrase
from calib_core.solve.single import CameraSolution, solve_camera


@dataclass
class CalibrateOptions:
    """Options of :func:`calibrate_session`.

    estimate_scale: None (default): estimate the sonar range scale wherever it is observable and the
        F test of :mod:`calib_core.solve.scale` finds a scale error; True: estimate it whenever
        observable (the old ``--scale``); False: hold it at 1 (``--no-scale``).
    robust: None, "huber" or "cauchy" (robust loss on each capture's Mahalanobis distance).
    detect: detect missing / auto entries afresh (False: use auto entries as they are).
    leave_one_out: compute leave-one-out residuals. joint: solve tied cameras jointly.
    check_outliers: run RANSAC to find captures that do not fit. seed: RANSAC sampling seed.
    """

    estimate_scale: bool | None = None
    robust: str | None = None
    detect: bool = True
    leave_one_out: bool = True
    joint: bool = True
    check_outliers: bool = True
    seed: int = 0


def _options(options) -> CalibrateOptions:
    if options is None:
        return CalibrateOptions()
    if isinstance(options, CalibrateOptions):
        o = options
    elif isinstance(options, dict):
        known = CalibrateOptions.__dataclass_fields__
        bad = [k for k in options if k not in known]
        if bad:
            raise ValueError(f"unknown calibrate options {bad}")
        o = CalibrateOptions(**options)
    else:
        raise TypeError("options must be a CalibrateOptions, a dict or None")
    if o.estimate_scale not in (None, True, False):
        raise SessionError(None, f"estimate_scale must be true, false or null (got {o.estimate_scale!r})")
    if o.robust not in (None, *ROBUST_LOSSES):
        raise SessionError(None, f"robust loss must be one of {', '.join(ROBUST_LOSSES)} (got {o.robust!r})")
    return o


def _plain(x):
    """JSON-ready: numpy -> lists/floats, inf/nan -> None."""
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return _plain(x.tolist())
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, (np.integer, int)):
        return int(x)
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(x) else None
    return x


def sigmas(cov6: np.ndarray) -> dict:
    """1- and 3-sigma per axis: rotation (deg, about the camera axes) and translation (mm)."""
    d = np.sqrt(np.maximum(np.diag(np.asarray(cov6, float)), 0))
    r, t = np.degrees(d[:3]), 1000 * d[3:]
    return {"sigma_1": {"rotation_deg": r, "translation_mm": t},
            "sigma_3": {"rotation_deg": 3 * r, "translation_mm": 3 * t}}


def _camera_entry(sol: CameraSolution, skipped: dict, intrinsics_rel: str) -> dict:
    cons = consistency(sol.chi2, sol.dof, f"{sol.name} (independent solve)")
    return {
        "T_cam_sonar": sol.T_cam_sonar, "rms_reprojection_px": sol.rms_px, "captures_used": sol.captures_used,
        "covariance": sol.cov, "solution": "independent", **sigmas(sol.cov),
        "chi2": sol.chi2, "dof": sol.dof, "variance_factor": sol.variance_factor, "consistency": cons,
        "independent": {"T_cam_sonar": sol.T_cam_sonar, "covariance": sol.cov, "rms_reprojection_px": sol.rms_px,
                        "variance_factor": sol.variance_factor, "consistency": cons},
        "residuals": sol.rows, "outliers": sol.outliers, "skipped": skipped, "intrinsics": intrinsics_rel,
        **({"covariance_with_scale": sol.cov_scale} if sol.cov_scale is not None else {}),
    }


def _solve_cameras(session, dets, opts, progress):
    """Independent solve of every camera: ({cam: CameraSolution}, {cam: entry}, errors)."""
    from calib_core import pipeline

    sols, entries, errors = {}, {}, []
    cam_names = list(session.cameras)
    single_scale = opts.estimate_scale if len(cam_names) == 1 else False
    for k, cam in enumerate(cam_names):
        if progress:
            progress(k, len(cam_names), f"solving {cam}")
        corr = pipeline.correspondences(session, dets, cam)
        model = session.camera_model(cam)
        try:
            cd = camera_data_from(model, dets, cam, corr)
            sol = solve_camera(cd, estimate_scale=single_scale, robust=opts.robust, loo=opts.leave_one_out,
                               check_outliers=opts.check_outliers, seed=opts.seed,
                               range_model=range_model(session))
        except SessionError as e:
            why = "; ".join(f"{c}: {r}" for c, r in corr.skipped.items())
            errors.append(e.problem + (f" (skipped: {why})" if why else ""))
            continue
        sols[cam] = sol
        rel = str(session.cameras[cam].intrinsics_path.relative_to(session.root))
        entries[cam] = _camera_entry(sol, corr.skipped, rel)
    return sols, entries, errors


def _scale_entry(value=1.0, sigma=None, estimated=False, source="none", note="", observable=False, test=None) -> dict:
    """The calibration.json ``range_scale`` block (contract: value, sigma, estimated, source)."""
    return {"value": value, "sigma": sigma, "estimated": estimated, "source": source, "note": note,
            "observable": observable, "test": test}


def _joint(session, sols, entries, opts, progress, warnings):
    """Joint solve of the cameras tied to the first by a stereo transform: (joint dict, scale dict) or (None, None)."""
    solved = [c for c in session.cameras if c in sols]
    ref = solved[0]
    links, stereo_info = {}, {}
    for c in solved[1:]:
        link = stereo_link(session, ref, c)
        if link is not None:
            T, cov, assumed, via = link
            links[c] = Link(T, cov)
            stereo_info[c] = {"T_cam_ref": T, "covariance": cov, "covariance_assumed": assumed,
                              **({"via": via} if via else {})}
    if not links:
        return None, None
    if progress:
        progress(len(solved), len(solved) + 1, "joint solve")
    rs = solve_rig(sols, links, ref, estimate_scale=opts.estimate_scale, robust=opts.robust)
    warnings += rs.warnings
    assumed = any(v["covariance_assumed"] for v in stereo_info.values())
    if assumed:
        warnings.append(f"joint solve: no stereo_covariance in session.yaml; {assumed_stereo_text()}")
    if stereo_factor_phrase(rs.stereo_factor, assumed):
        warnings.append(stereo_factor_phrase(rs.stereo_factor, assumed))
    cons = consistency(rs.chi2, rs.dof, "joint solve")
    joint = {"reference": ref, "cameras": rs.cameras, "stereo": stereo_info,
             "T_cam_ref_solved": rs.T_cam_ref, "rms_reprojection_px": rs.rms_px, "chi2": rs.chi2, "dof": rs.dof,
             "variance_factor": rs.variance_factor, "consistency": cons, "mahalanobis": rs.mahalanobis,
             "stereo_variance_factor": rs.stereo_factor}
    for c in rs.cameras:
        entries[c].update({"T_cam_sonar": rs.T_cam_sonar[c], "covariance": rs.cov[c], "solution": "joint",
                           "rms_reprojection_px": rs.rms_px[c], "consistency": cons, **sigmas(rs.cov[c])})
        if c in rs.cov_with_scale:
            entries[c]["covariance_with_scale"] = rs.cov_with_scale[c]
    source = f"joint solve of {' + '.join(rs.cameras)} with the stereo transform"
    limit = stereo_limit_note(rs.scale_sigma, rs.scale_sigma_detections, assumed)
    scale = _scale_entry(rs.scale, rs.scale_sigma, rs.scale_sigma is not None, source, rs.scale_note + limit,
                         rs.scale_observable, rs.scale_test)
    return joint, scale


def _single_scale(session, sols: dict, n_cams: int, opts) -> dict:
    """The range scale block when there is no joint solve."""
    if opts.estimate_scale is False:
        return _scale_entry(note="held at 1 (--no-scale)")
    if n_cams == 1 and sols:
        only = next(iter(sols.values()))
        source = f"{only.name} alone"
        if only.scale_observable:
            source = f"{only.name}: sphere ranges from its apparent size ({_range_systematics(session)})"
        caution = size_route_caution(only.scale, only.scale_sigma is not None) if only.scale_observable else ""
        entry = _scale_entry(only.scale, only.scale_sigma, only.scale_sigma is not None, source,
                             only.scale_note + caution, only.scale_observable, only.scale_test)
        if (only.scale_test or {}).get("outline_bias"):
            entry["outline_bias"] = {only.name: only.scale_test["outline_bias"]}
        return entry
    if len(sols) >= 2:
        shared = _shared(session, sols, opts)
        if shared is not None:
            return shared
    return _scale_entry(note="not observable: the cameras have no stereo transform in session.yaml to tie them and "
                             "fewer than two record the sphere's range (apparent size)")


def _range_systematics(session) -> str:
    """The systematics of image ranges, said once: diameter tolerance and outline error, each
    marked when assumed."""
    d, d_assumed = diameter_sigma(session)
    o, o_assumed = outline_sigma_px(session)
    outline = (f"each camera's outline bias estimated with it (tolerance ±{o:.1f} px" if o > 0 else
               "outline bias held at 0 (sphere.outline_sigma_px: 0")
    return (f"diameter {1000 * session.sphere_diameter_m:.1f} ± {1000 * d:.1f} mm"
            f"{' (assumed: no sphere.diameter_sigma in session.yaml)' if d_assumed else ''}; {outline}"
            f"{'; assumed: no sphere.outline_sigma_px in session.yaml' if o_assumed else ''})")


def _shared(session, sols: dict, opts) -> dict | None:
    """The range scale from several cameras' diameter evidence (calib_core.solve.shared_scale), or None."""
    cams = {c: (s.data, s.used, s.T_cam_sonar) for c, s in sols.items()}
    mode = "always" if opts.estimate_scale is True else "auto"
    model = range_model(session)
    # the systematic common to all cameras: the diameter's (each camera's outline bias is fitted)
    rel = model.diameter_rel_sigma if model.estimates_outline else \
        float(np.sqrt(np.mean([range_rel_sigma(session, s.data) ** 2 for s in sols.values()])))
    sh = shared_scale(cams, mode, rel, opts.robust, model)
    if sh is None:
        return None
    source = (f"{' + '.join(sh.per_camera)}: sphere ranges from its apparent size, one scale for all "
              f"({_range_systematics(session)})")
    entry = _scale_entry(sh.value, sh.sigma if sh.estimated else None, sh.estimated, source,
                         sh.note + size_route_caution(sh.value, sh.estimated), True, sh.test)
    entry["per_camera"] = sh.per_camera
    outlines = {c: v["outline_bias"] for c, v in sh.per_camera.items() if "outline_bias" in v}
    if outlines:
        entry["outline_bias"] = outlines
    entry["poses"] = sh.poses
    return entry


def _apply_shared_poses(poses: dict, entries: dict) -> None:
    """Each camera's pose refitted at the shared range scale replaces its s = 1 pose (``independent`` keeps that)."""
    for c, (T, cov) in poses.items():
        entries[c].update({"T_cam_sonar": T, "covariance": cov, "solution": "shared range scale", **sigmas(cov)})


def calibrate_session(session, detections: dict, options=None, progress=None) -> dict:
    """Calibrate every camera of ``session`` to the sonar; return the calibration.json content.

    Raises SessionError (naming detections.yaml or session.yaml) when no camera has enough
    usable correspondences, or for bad options / stereo covariances.
    """
    from calib_core import pipeline
    from calib_core.detections import detections_path

    opts = _options(options)
    dets = pipeline.detect_session(session, detections, progress=progress) if opts.detect else detections
    sols, entries, errors = _solve_cameras(session, dets, opts, progress)
    if not sols:
        raise SessionError(detections_path(session), "no camera could be calibrated: " + " | ".join(errors))
    warnings = [w for s in sols.values() for w in s.warnings]
    warnings += [f"{e}; this camera was not calibrated" for e in errors]
    joint, scale = (None, None)
    solved = [c for c in session.cameras if c in sols]
    if len(solved) >= 2 and opts.joint:
        joint, scale = _joint(session, sols, entries, opts, progress, warnings)
    if scale is None:
        scale = _single_scale(session, sols, len(session.cameras), opts)
        _apply_shared_poses(scale.pop("poses", {}), entries)
    overall = joint["consistency"] if joint else (entries[solved[0]]["consistency"] if len(solved) == 1 else None)
    for c in [overall] if overall else [entries[c]["consistency"] for c in solved]:
        if is_warning(c):
            warnings.append(consistency_phrase(c))
    tab = None
    if len(solved) >= 2:
        a, b = solved[0], solved[1]
        tab = table_i({c: sols[c].T_cam_sonar for c in (a, b)}, a, b, find_stereo(session.stereo, a, b),
                      session.measured_m, {c: sols[c].cov for c in (a, b)})
        tab["note"] = "independent per-camera solves, as in the paper"
    if progress:
        progress(1, 1, "done")
    result = {
        "format": CALIBRATION_FORMAT,
        "session": session.name,
        "tool": {"name": "sonarcal", "version": __version__},
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "options": asdict(opts),
        "cameras": entries,
        "range_scale": scale,
        "consistency": overall,
        "joint": joint,
        "table_i": tab,
        "warnings": warnings,
    }
    return _plain(result)
