"""Per-capture pictures and numbers for the HTML report (no HTML here).

For each capture: the detection thumbnails (image crop with the detected ellipse/centre and
the reprojected sonar centre; the sonar cloud around the detected centre), the segmentation
overlay (the paper's Fig. 3), the coloured cloud (Figs. 4 and 5) and the reprojection
residual per camera. Problems with one file (missing image, unreadable cloud) are recorded
in ``CaptureView.problems`` and the rest of the report goes on.

Range scale: calibration.json's ``T_cam_sonar`` maps *true* sonar points; cloud points are
divided by ``range_scale.value`` first (1 when absent).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib_core import fusion
from calib_core.detect.reasons import entry_problem, residual_problem
from calib_core.errors import SessionError
from calib_core.geometry import look_at_T_cam_world
from calib_core.camera import CameraModel
from calib_core.report.render import colourise, crop_thumbnail, data_uri, fit_width, oblique_view, render_points


UNCOLOURED = (235, 140, 50)  # orange: points no camera sees (or hidden), in the coloured-cloud renders


@dataclass
class ReportOptions:
    """Knobs of the report. ``mask_radius_px`` None: 0.6 % of the image width (~12 px at 1080p)."""

    mask_radius_px: float | None = None
    overlay_width_px: int = 960
    thumb_px: int = 200
    render_size_px: tuple[int, int] = (800, 500)
    max_render_points: int = 400_000
    jpeg_quality: int = 82


@dataclass
class CaptureView:
    """What the report shows for one capture. Images are data URIs (or None)."""

    id: str
    n_points: int | None = None
    thumbs: dict[str, str] = field(default_factory=dict)       # sensor -> thumbnail
    overlays: dict[str, str] = field(default_factory=dict)     # cam -> segmentation overlay
    coloured_cloud: str | None = None
    coloured_fraction: float | None = None
    reprojected_uv: dict[str, list] = field(default_factory=dict)
    residual_px: dict[str, list] = field(default_factory=dict)  # cam -> [du, dv] (reprojected - detected)
    problems: list[str] = field(default_factory=list)


def calibrated_T(calibration: dict | None, cam: str) -> np.ndarray | None:
    c = ((calibration or {}).get("cameras") or {}).get(cam)
    if not isinstance(c, dict) or c.get("T_cam_sonar") is None:
        return None
    T = np.asarray(c["T_cam_sonar"], float)
    return T if T.shape == (4, 4) and np.isfinite(T).all() else None


def range_scale(calibration: dict | None) -> float:
    s = (calibration or {}).get("range_scale")
    v = s.get("value") if isinstance(s, dict) else s
    return float(v) if isinstance(v, (int, float)) and np.isfinite(v) and v > 0 else 1.0


def _centre(entry: dict | None):
    if not isinstance(entry, dict) or entry.get("status") == "rejected" or entry.get("center") is None:
        return None
    return np.asarray(entry["center"], float)


def sonar_thumbnail(points_true_m: np.ndarray, centre_m: np.ndarray, radius_m: float, size_px: int) -> np.ndarray:
    """The cloud within 3 sphere radii of the detected centre, seen from the sonar's side,
    coloured by range, with the fitted sphere's outline."""
    P = points_true_m[np.linalg.norm(points_true_m - centre_m, axis=1) < 3 * radius_m]
    dist = float(np.linalg.norm(centre_m))
    view_dir = centre_m / dist if dist > 1e-6 else np.array([1.0, 0.0, 0.0])
    up = np.array([0.0, 0.0, 1.0]) if abs(view_dir[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    eye = centre_m - view_dir * 8 * radius_m
    T_view = look_at_T_cam_world(eye, centre_m, up)
    f = size_px / 2 * 8 / 3.2  # 3.2 radii from the centre to the border
    cam = CameraModel(size_px, size_px, [[f, 0, size_px / 2 - 0.5], [0, f, size_px / 2 - 0.5], [0, 0, 1]])
    img = render_points(P, colourise(np.linalg.norm(P, axis=1)) if len(P) else np.zeros((0, 3), np.uint8), cam,
                        T_view, splat_radius_px=2, background=(20, 20, 30), depth_shading=0.0)
    r_px = f * radius_m / (8 * radius_m)
    fusion.draw_marker(img, (size_px / 2 - 0.5, size_px / 2 - 0.5), (255, 255, 255), "circle", size_px=r_px)
    fusion.draw_marker(img, (size_px / 2 - 0.5, size_px / 2 - 0.5), (255, 255, 255), "cross", size_px=6)
    return img


def capture_view(session, cap, detections: dict, calibration: dict | None, models: dict[str, CameraModel],
                 opts: ReportOptions) -> CaptureView:
    """Everything the report shows for capture ``cap`` (a session Capture)."""
    view = CaptureView(cap.id)
    dets = detections.get(cap.id, {})
    s = range_scale(calibration)
    P = _load_points(cap, s, view)
    sonar_c = _centre(dets.get("sonar"))
    if entry_problem("sonar", dets.get("sonar")):
        view.problems.append(entry_problem("sonar", dets.get("sonar")))
    if P is not None and sonar_c is not None:
        X = sonar_c / s
        view.thumbs["sonar"] = data_uri(sonar_thumbnail(P, X, session.sphere_radius_m, opts.thumb_px), "png")
    ctx = _Context(session, calibration, opts, view, s, P, sonar_c)
    views = []
    for cam, path in cap.image_paths.items():
        cv = _camera_part(ctx, cam, path, models.get(cam), dets.get(cam) or {})
        if cv is not None:
            views.append(cv)
    if views and P is not None:
        _coloured_cloud(view, P, views, opts)
    return view


@dataclass
class _Context:
    """What every camera of one capture shares while its view is built."""

    session: object
    calibration: dict | None
    opts: ReportOptions
    view: CaptureView
    scale: float  # range scale: true sonar points are cloud points / scale
    P: np.ndarray | None  # the cloud's true points (None when it could not be read)
    sonar_c: np.ndarray | None  # the detected sonar centre (cloud units)


def _load_points(cap, s: float, view: CaptureView) -> np.ndarray | None:
    from calib_core.io.clouds import load_cloud

    try:
        cloud = load_cloud(cap.cloud_path)
    except SessionError as e:
        view.problems.append(str(e))
        return None
    P = cloud.points_m / s
    view.n_points = len(P)
    return P


def _camera_part(ctx: _Context, cam: str, path, model: CameraModel | None, entry: dict):
    """Thumbnail, residual and overlay of camera ``cam`` (into ``ctx.view``); its CameraView for
    colouring the cloud when calibrated, else None."""
    from calib_core.io.images import load_image

    view = ctx.view
    try:
        img = load_image(path)
    except SessionError as e:
        view.problems.append(str(e))
        return None
    if model is None or img.shape[:2] != (model.height_px, model.width_px):
        view.problems.append(f"{path}: image size does not match the intrinsics of {cam}" if model else
                             f"{cam}: intrinsics unavailable")
        return None
    T = calibrated_T(ctx.calibration, cam)
    det_c = _centre(entry)
    reproj = _reprojection(ctx, cam, model, T, det_c)
    for why in (entry_problem(cam, entry), residual_problem(cam, view.residual_px.get(cam))):
        if why:
            view.problems.append(why)
    drawn = fusion.draw_detection(img, det_c, entry.get("ellipse_px"), reproj, labels=False)
    half = _thumb_half_px(ctx, model, T, entry)
    view.thumbs[cam] = data_uri(crop_thumbnail(drawn, det_c if det_c is not None else reproj, half, ctx.opts.thumb_px))
    if T is None or ctx.P is None:
        return None
    uv, _, ok = fusion.project_cloud(ctx.P, T, model)
    opts = ctx.opts
    r = opts.mask_radius_px if opts.mask_radius_px is not None else 0.006 * model.width_px
    mask = fusion.segmentation_mask(model, uv, r, ok)
    over = fusion.draw_detection(fusion.overlay(img, mask, (40, 255, 80), 0.4), det_c, entry.get("ellipse_px"), reproj)
    view.overlays[cam] = data_uri(fit_width(over, opts.overlay_width_px), quality=opts.jpeg_quality)
    return fusion.CameraView(cam, img, model, T)


def _reprojection(ctx: _Context, cam: str, model: CameraModel, T, det_c):
    """The sonar centre reprojected into camera ``cam`` (pixels, None when it cannot be), and
    its residual against the image detection (both recorded in ``ctx.view``)."""
    if T is None or ctx.sonar_c is None:
        return None
    X = ctx.sonar_c / ctx.scale
    uv, _, ok = fusion.project_cloud(X[None], T, model)
    if not ok[0]:
        return None
    reproj = model.project((T[:3, :3] @ X + T[:3, 3])[None])[0]
    ctx.view.reprojected_uv[cam] = [float(v) for v in reproj]
    if det_c is not None:
        ctx.view.residual_px[cam] = [float(v) for v in reproj - det_c]
    return reproj


def _thumb_half_px(ctx: _Context, model: CameraModel, T, entry: dict) -> float:
    """Half the side of a camera thumbnail: 2.2 sphere radii (detected, else from the sphere's
    depth), else 6 % of the image width."""
    half = 0.06 * model.width_px
    if isinstance(entry.get("radius_px"), (int, float)) and entry["radius_px"] > 0:
        half = 2.2 * float(entry["radius_px"])
    elif T is not None and ctx.sonar_c is not None:  # apparent radius from the sphere's depth
        z = float(T[2, :3] @ (ctx.sonar_c / ctx.scale) + T[2, 3])
        half = 2.2 * model.fx * ctx.session.sphere_radius_m / z if z > 0.05 else half
    return half


def _coloured_cloud(view: CaptureView, P: np.ndarray, views: list, opts: ReportOptions) -> None:
    """The cloud coloured by the cameras (Figs. 4-5), rendered obliquely, into ``view``."""
    colours, coloured, _ = fusion.colour_cloud_multi(P, views, fallback=UNCOLOURED)
    view.coloured_fraction = float(coloured.mean()) if len(coloured) else 0.0
    keep = np.arange(len(P))
    if len(P) > opts.max_render_points:
        keep = np.random.default_rng(0).choice(len(P), opts.max_render_points, replace=False)
    w, h = opts.render_size_px
    focus = P[coloured] if coloured.sum() >= 10 else P[keep]  # frame what the cameras see
    vcam, T_view = oblique_view(focus, views[0].T_cam_sonar, w, h)
    img = render_points(P[keep], colours[keep], vcam, T_view, splat_radius_px=2 if len(keep) < 50_000 else 1)
    view.coloured_cloud = data_uri(img, quality=opts.jpeg_quality)
