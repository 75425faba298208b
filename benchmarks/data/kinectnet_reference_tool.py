"""Helper for the hand check of kinectnet-dev ball centres (see README.md here).

Not a detector and not used by one: it proposes outline points from a plain colour threshold
(the ball is yellow; this tool may know that, the detector must not), fits the exact
silhouette cone to them robustly, and renders zoomed crops with the proposed outline and
centre drawn on them so that a person can accept, correct or flag each image by eye.

    python benchmarks/data/kinectnet_reference_tool.py SESSION OUT_DIR
writes OUT_DIR/proposals.yaml and OUT_DIR/<cam>_sheet.png (crops x3, grid every 10 px).
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np
import yaml

from calib_core.detect.image.cone import centre_uv_and_cov, fit_cone, silhouette_uv
from calib_core.session import load_session


def outline_points(img_rgb: np.ndarray) -> np.ndarray | None:
    hsv = cv2.cvtColor(img_rgb, cv2.COLOR_RGB2HSV)
    h, s, v = hsv[..., 0], hsv[..., 1], hsv[..., 2]
    mask = ((h >= 18) & (h <= 40) & (s >= 90) & (v >= 90)).astype(np.uint8)
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    n, lab, st, _ = cv2.connectedComponentsWithStats(mask)
    if n < 2:
        return None
    i = 1 + int(np.argmax(st[1:, cv2.CC_STAT_AREA]))
    blob = (lab == i).astype(np.uint8)
    cs, _ = cv2.findContours(blob, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    c = max(cs, key=len)[:, 0, :].astype(float)
    return c


def propose(session_dir: str, out_dir: str) -> None:
    ses = load_session(session_dir)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    props: dict = {}
    rng = np.random.default_rng(0)
    for cam in ses.cameras:
        model = ses.camera_model(cam)
        tiles = []
        for cap in ses.captures:
            img = cv2.cvtColor(cv2.imread(str(cap.image_paths[cam])), cv2.COLOR_BGR2RGB)
            pts = outline_points(img)
            entry = {}
            if pts is not None and len(pts) > 20:
                fit = fit_cone(model, model.normalize(pts), (1e-3, 1.2), inlier_px=1.0, rng=rng)
                if fit is not None:
                    uv, _ = centre_uv_and_cov(model, fit)
                    sil = silhouette_uv(model, fit.w, fit.a_rad, n=180)
                    entry = {"centre_uv_px": [round(float(uv[0]), 2), round(float(uv[1]), 2)],
                             "inlier_fraction": round(fit.inlier_fraction, 3),
                             "radius_px": round(float(np.mean(np.linalg.norm(sil - sil.mean(0), axis=1))), 1)}
                    tiles.append(_tile(img, uv, sil, pts[fit.inliers], f"{cam} {cap.id}"))
            props.setdefault(cam, {})[cap.id] = entry
            if not entry:
                tiles.append(_tile(img, None, None, None, f"{cam} {cap.id} none"))
        while len(tiles) % 6:
            tiles.append(np.zeros_like(tiles[0]))
        sheet = np.vstack([np.hstack(tiles[i:i + 6]) for i in range(0, len(tiles), 6)])
        cv2.imwrite(str(out / f"{cam}_sheet.png"), cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR))
    (out / "proposals.yaml").write_text(yaml.safe_dump(props, sort_keys=True))


def _tile(img, uv, sil, inl, label, size=300):
    H, W = img.shape[:2]
    if uv is None:
        t = cv2.resize(img, (size, size * H // W))
        t = np.pad(t, ((0, size - t.shape[0]), (0, 0), (0, 0)))
    else:
        r = float(np.max(np.linalg.norm(sil - sil.mean(0), axis=1))) * 1.35 + 6
        cx, cy = sil.mean(0)
        z = size / (2 * r)
        M = np.array([[z, 0, size / 2 - z * cx], [0, z, size / 2 - z * cy]])
        t = cv2.warpAffine(img, M, (size, size), flags=cv2.INTER_NEAREST)
        for g in range(int(cx - r) // 10 * 10, int(cx + r) + 10, 10):
            x = int(z * g + M[0, 2])
            cv2.line(t, (x, 0), (x, 4), (255, 255, 255), 1)
        pp = lambda p: (int(round(z * p[0] + M[0, 2])), int(round(z * p[1] + M[1, 2])))
        poly = np.array([pp(p) for p in sil], np.int32)
        cv2.polylines(t, [poly], True, (255, 0, 255), 1)
        c = pp(uv)
        cv2.drawMarker(t, c, (255, 0, 0), cv2.MARKER_CROSS, 12, 1)
    cv2.putText(t, label, (4, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 0, 0), 1)
    return t


if __name__ == "__main__":
    propose(sys.argv[1], sys.argv[2])
