"""Mirror pairs: a ball and its copy in a plane mirror (a glass wall, the water surface seen from
below, a shiny hull).

Physics that holds for any plane mirror: the camera and the ball are on the same side of it, so
the virtual ball (the copy) is always farther from the camera than the ball, and no brighter
(reflectance <= 1). Its image is the ball's seen by the camera reflected in the mirror: to first
order the ball's image flipped across the line perpendicular to the pair's axis (the line
through the two centres), rescaled to the copy's size.

The ball's own texture flips that way. Shading that depends on the view and the light (a glossy
highlight, sun caustics seen from above) may keep its side instead (measured on the tank kind: a
glass-pane copy with caustics on top correlated 0.91 unflipped and 0.08 flipped); but two real
balls side by side under one light look alike unflipped too, so only the flip is evidence of a
mirror. And a flip explains nothing when the disc looks the same flipped (shading symmetric about
the line, e.g. lit from above with the pair side by side): two like boulders on a seabed
correlated 0.83 flipped and 0.80 unflipped (underwater kind). So the flip must explain the pair
better than no flip, by FLIP_MARGIN; a pair alike both ways, or only unflipped, stays "two round
objects" (the session's sonar chooses).

So two round outlines are a mirror pair when (all measured, none tuned to a scene):

- the copy's disc, sampled flipped across that line and rescaled to the ball's
  size, correlates with the ball's disc: correlation at least MIN_CORR of what the image noise
  allows (the correlation of two noisy copies of one picture is below 1 by the noise's share of
  the variance; a flat disc, noise only, gives no evidence), and by FLIP_MARGIN more than
  unflipped;
- the two mean colours point the same way (the reflection scales the colour; a different ball
  has another colour) and the copy is no brighter than the ball (beyond BRIGHTER_FRACTION: the
  longer path's veil adds a little light to a dark ball's copy);
- the copy's cone range exceeds the ball's by more than RANGE_SIGMAS of their uncertainty.

Then the nearer one is the ball. A copy whose disc is symmetric about that line (a plain ball lit
from above beside a glass wall) is not recognised: one image cannot tell it from a twin ball.

With the camera model and both 3D centres (cone axis times range), the flip is taken exactly
(:func:`exact_samples`): the mirror of the pair is the plane bisecting the two centres; a point X
on the ball's visible surface is seen in the copy at the projection of its reflection X'. That
pixel shows X as seen from the reflected camera, so for a matte surface (its print, its diffuse
shading, caustics falling on it) the two pixels agree, whatever the plane's tilt to the view.
The first-order flip does not hold when the mirror is seen at an angle (a glass wall receding
from the camera): the copy then shows another side of the ball (tank s1010: 0.08 flipped). The
"no flip" hypothesis becomes a twin ball at the far centre: X translated by the centres'
difference. Only points seen on both spheres, away from either limb, are compared.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

MIN_CORR = 0.8  # correlation of the rescaled discs, over what the noise allows
FLIP_MARGIN = 0.1  # the flip must explain the pair this much better than no flip
BRIGHTER_FRACTION = 0.1  # the copy's mean grey may exceed the ball's by this share
MIN_COLOUR_COS = 0.985  # cosine of the mean colours' angle (about 10 deg)
RANGE_SIGMAS = 3.0  # the copy's range exceeds the ball's by this many sigmas of the difference
DISC_FRACTION = 0.85  # the disc sampled (of the apparent radius): inside the outline's blur
GRID = 21  # samples per disc diameter
MIN_SEEN = 0.5  # share of the disc samples in the image (both discs) needed to compare
MIN_VIEW_COS = 0.3  # exact flip: surface points this far from the limb on both spheres (cos of the view angle)
MIN_SAMPLES = 30  # exact flip: surface points seen on both spheres needed to compare


@dataclass(frozen=True)
class MirrorEvidence:
    """How two round outlines compare as a ball and its mirror copy."""

    flip_corr: float  # correlation of the copy's flipped, rescaled disc with the ball's / the noise's ceiling
    direct_corr: float  # the same without the flip
    colour_cos: float  # cosine between the two mean colours
    brightness_ratio: float  # copy's mean grey over the ball's
    range_sigmas: float  # copy's range minus the ball's, in sigmas of the difference

    def is_pair(self) -> bool:
        return bool(self.flip_corr >= MIN_CORR and self.flip_corr >= self.direct_corr + FLIP_MARGIN
                    and self.colour_cos >= MIN_COLOUR_COS and self.brightness_ratio <= 1.0 + BRIGHTER_FRACTION and self.range_sigmas >= RANGE_SIGMAS)


def _unit_disc(n: int = GRID) -> np.ndarray:
    t = np.linspace(-1.0, 1.0, n)
    q = np.stack(np.meshgrid(t, t), axis=-1).reshape(-1, 2)
    return q[np.hypot(q[:, 0], q[:, 1]) <= 1.0]


def _in_image(p: np.ndarray, W: int, H: int) -> np.ndarray:
    return (p[:, 0] >= 0) & (p[:, 0] <= W - 1) & (p[:, 1] >= 0) & (p[:, 1] <= H - 1)


def _blur_sigma(radius: float) -> float:
    return max(0.33 * 2 * DISC_FRACTION * radius / (GRID - 1), 0.5)


def _sample(img: np.ndarray, centre, radius: float, q: np.ndarray) -> np.ndarray:
    """(N, C) float samples of ``img`` at centre + DISC_FRACTION * radius * q (bilinear),
    after a blur of a third of the sample spacing (no aliasing of fine texture)."""
    return _sample_at(img, np.asarray(centre, float) + DISC_FRACTION * radius * q, _blur_sigma(radius))


def _sample_at(img: np.ndarray, p: np.ndarray, sigma: float) -> np.ndarray:
    """(N, C) float samples of ``img`` at pixels ``p`` (N,2; bilinear) after a Gaussian blur of
    ``sigma`` px."""
    x0, y0 = np.floor(p.min(axis=0) - 4).astype(int)
    x1, y1 = np.ceil(p.max(axis=0) + 5).astype(int)
    H, W = img.shape[:2]
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
    roi = img[y0:y1, x0:x1].astype(np.float32)
    roi = cv2.GaussianBlur(roi, (0, 0), sigma)
    mx = (p[:, 0] - x0).astype(np.float32).reshape(-1, 1)
    my = (p[:, 1] - y0).astype(np.float32).reshape(-1, 1)
    out = cv2.remap(roi, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return out.reshape(len(p), -1)


def _ceiling(x: np.ndarray, noise_var: float) -> float:
    """Share of a sampled disc's variance that is picture, not noise (0-1)."""
    v = float(x.var(axis=0).mean())
    return max(v - noise_var, 0.0) / v if v > 0 else 0.0


def _corr(a: np.ndarray, b: np.ndarray, noise_var: float) -> float:
    """Correlation of two sampled discs over the most their noise allows (1: one picture)."""
    ceiling = float(np.sqrt(_ceiling(a, noise_var) * _ceiling(b, noise_var)))
    if ceiling < 0.25:  # noise only (a flat disc): no evidence either way
        return 0.0
    a = a - a.mean(axis=0)
    b = b - b.mean(axis=0)
    den = float(np.sqrt((a * a).sum() * (b * b).sum()))
    return float((a * b).sum() / den / ceiling) if den > 0 else 0.0


def flat_samples(near: dict, far: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pixels (N,2 each) of the ball's disc samples, of the copy's flipped across the line
    perpendicular to the pair's axis (first order), and of the copy's unflipped."""
    c_a, c_b = np.asarray(near["centre_px"], float), np.asarray(far["centre_px"], float)
    axis = c_b - c_a
    e = axis / max(float(np.linalg.norm(axis)), 1e-9)
    q = _unit_disc()
    flipped = q - 2.0 * (q @ e)[:, None] * e[None, :]
    k_a, k_b = DISC_FRACTION * near["radius_px"], DISC_FRACTION * far["radius_px"]
    return c_a + k_a * q, c_b + k_b * flipped, c_b + k_b * q


def _on_sphere(rays: np.ndarray, centre_m: np.ndarray, radius_m: float) -> np.ndarray:
    """Nearest intersections (N,3, m; NaN for a miss) of unit camera rays with a sphere."""
    b = rays @ centre_m
    disc = b * b - (centre_m @ centre_m - radius_m ** 2)
    with np.errstate(invalid="ignore"):
        t = b - np.sqrt(disc)
    return rays * np.where(disc >= 0, t, np.nan)[:, None]


def _view_cos(points_m: np.ndarray, centre_m: np.ndarray) -> np.ndarray:
    """Cosine between each surface point's outward normal and its direction to the camera."""
    nrm = points_m - centre_m
    return -np.einsum("ij,ij->i", nrm, points_m) / (np.linalg.norm(nrm, axis=1) * np.linalg.norm(points_m, axis=1))


def exact_samples(cam, near: dict, far: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """As :func:`flat_samples`, exactly (see the module doc): the ball's visible surface points
    X on its disc samples, the projection of their reflection in the plane bisecting the two 3D
    centres (``centre_cam_m``), and of X moved to the far centre (a twin); only points at least
    MIN_VIEW_COS from the limb on both spheres."""
    c_a, c_b = np.asarray(near["centre_cam_m"], float), np.asarray(far["centre_cam_m"], float)
    r_m = float(near["sphere_radius_m"])
    q = _unit_disc()
    X = _on_sphere(cam.rays(np.asarray(near["centre_px"], float) + near["radius_px"] * q), c_a, r_m)
    n = (c_b - c_a) / max(float(np.linalg.norm(c_b - c_a)), 1e-12)
    X_m = X - 2.0 * ((X - 0.5 * (c_a + c_b)) @ n)[:, None] * n[None, :]
    X_t = X + (c_b - c_a)
    with np.errstate(invalid="ignore"):
        keep = ((_view_cos(X, c_a) >= MIN_VIEW_COS) & (_view_cos(X_m, c_b) >= MIN_VIEW_COS)
                & (_view_cos(X_t, c_b) >= MIN_VIEW_COS))
    X, X_m, X_t = X[keep], X_m[keep], X_t[keep]
    return cam.project(X), cam.project(X_m), cam.project(X_t)


def compare(img: np.ndarray, near: dict, far: dict, noise_dn: float, cam=None) -> MirrorEvidence:
    """Evidence that ``far`` is the mirror copy of ``near``. Each is a dict with ``centre_px``,
    ``radius_px``, ``range_m`` and ``range_sigma_m`` (and, for the exact flip with ``cam``, the
    camera model, ``centre_cam_m`` and ``sphere_radius_m``); ``noise_dn`` the image noise (grey
    levels)."""
    exact = cam is not None and "centre_cam_m" in near and "centre_cam_m" in far
    p_a, p_flip, p_direct = exact_samples(cam, near, far) if exact else flat_samples(near, far)
    # only where both discs are in the image (a copy cut by the border is compared on its part)
    H, W = img.shape[:2]
    seen = _in_image(p_a, W, H) & _in_image(p_flip, W, H) & _in_image(p_direct, W, H)
    if seen.sum() < MIN_SEEN * len(p_a) or seen.sum() < (MIN_SAMPLES if exact else 1):
        return MirrorEvidence(0.0, 0.0, 0.0, np.inf, 0.0)
    s_a, s_b = _blur_sigma(near["radius_px"]), _blur_sigma(far["radius_px"])
    a, b_flip, b_direct = (_sample_at(img, pp[seen], sg) for pp, sg in ((p_a, s_a), (p_flip, s_b), (p_direct, s_b)))
    # the blur before sampling lowers the noise variance by 1 / (4 pi sigma^2)
    sigma = _blur_sigma(min(near["radius_px"], far["radius_px"]))
    noise_var = noise_dn ** 2 / (4 * np.pi * sigma ** 2)
    mean_a, mean_b = a.mean(axis=0), b_direct.mean(axis=0)
    cos = float(mean_a @ mean_b / max(np.linalg.norm(mean_a) * np.linalg.norm(mean_b), 1e-9))
    ratio = float(mean_b.mean() / max(mean_a.mean(), 1e-6))
    d_sigma = float(np.hypot(near["range_sigma_m"], far["range_sigma_m"]))
    range_sig = float((far["range_m"] - near["range_m"]) / max(d_sigma, 1e-9))
    return MirrorEvidence(_corr(a, b_flip, noise_var), _corr(a, b_direct, noise_var), cos, ratio, range_sig)


def evidence(img: np.ndarray, near: dict, far: dict, noise_dn: float, cam) -> MirrorEvidence:
    """The exact flip's evidence (:func:`compare` with ``cam``) when it finds a pair, else the
    first-order flip's. The first order is the exact flip's limit for a mirror whose normal lies in
    the image plane; the exact flip compares only the surface seen on both spheres, which on a
    small or obliquely mirrored pair may be too little to tell the flip from the twin. Each is
    the same strict test of one hypothesis (a plane mirror), on two samplings of the discs."""
    ev = compare(img, near, far, noise_dn, cam)
    return ev if ev.is_pair() else compare(img, near, far, noise_dn)


def noise_sigma_dn(img: np.ndarray) -> float:
    """Robust per-channel image noise (grey levels): the median absolute response of Immerkaer's
    Laplacian-difference kernel (6 sigma for white noise) on a half-resolution subsample of each
    colour channel; the median ignores the edges of tiles and texture, which a mean counts as
    noise."""
    sub = np.ascontiguousarray(np.asarray(img)[::2, ::2]).astype(np.float32)
    k = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)
    r = cv2.filter2D(sub, -1, k)[1:-1, 1:-1]
    return float(np.median(np.abs(r)) / (0.6745 * 6.0))
