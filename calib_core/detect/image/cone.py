"""The silhouette cone of a sphere, fitted to edge points in normalised camera coordinates.

A sphere of radius ``r`` whose centre lies at distance ``d`` along the unit direction ``w``
(camera frame, OpenCV axes) is seen under the half-angle ``a`` with ``sin(a) = r / d``.
Its silhouette is the set of rays ``v`` with ``v . w = cos(a)``; in normalised undistorted
coordinates ``x = (X/Z, Y/Z, 1)`` this is the conic ``x^T (cos^2(a) I - w w^T) x = 0``.
The perspective projection of the centre is ``w`` itself (``K w`` then lens distortion), not
the centre of the ellipse.

The fit works on the cone directly (3 parameters: the axis ``w`` and the angle ``a``), which is
the exact model of a sphere's silhouette; an unconstrained 5-parameter conic fitted by least
squares (:func:`fit_conic_normalised`) gives a start via the eigen-decomposition of ``Q``.
Residuals are angles on the unit sphere converted to raw pixels with the local scale of
the camera model, so the robust thresholds are in pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_core.camera import CameraModel, pi_jacobian


@dataclass
class ConeFit:
    """Result of :func:`fit_cone`.

    Attributes:
        w: (3,) unit axis of the cone (direction camera -> sphere centre), camera frame.
        a_rad: half-angle of the cone.
        inliers: (N,) bool mask over the input edge points.
        residuals_px: (N,) signed residuals in raw pixels (positive = outside the cone).
        sigma_px: robust spread of the inlier residuals (px).
        cov_params: (3,3) covariance of (p1, p2, a) where w moves by p1 e1 + p2 e2 (rad^2).
        basis: (3,3) rows w, e1, e2 at the solution.
    """

    w: np.ndarray
    a_rad: float
    inliers: np.ndarray
    residuals_px: np.ndarray
    sigma_px: float
    cov_params: np.ndarray
    basis: np.ndarray
    reading: str = ""  # which edges it was fitted to, when a caller records it
    edge_uv_px: np.ndarray | None = None  # (N,2) the edge points fitted, when a caller records them
    smear: object | None = None  # the motion smear measured around the outline (image.smear.Smear), when read as one

    @property
    def inlier_fraction(self) -> float:
        return float(self.inliers.mean()) if self.inliers.size else 0.0


def rays_from_xy(xy: np.ndarray) -> np.ndarray:
    """Unit rays (N,3) for normalised undistorted points (N,2)."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    v = np.column_stack([xy, np.ones(len(xy))])
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def orthonormal_basis(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors e1, e2 completing the unit vector ``w`` to a right-handed basis."""
    x, y, z = float(w[0]), float(w[1]), float(w[2])
    if abs(x) < 0.9:  # e1 = w x (1,0,0)
        e1 = np.array([0.0, z, -y])
    else:  # e1 = w x (0,1,0)
        e1 = np.array([-z, 0.0, x])
    e1 /= np.sqrt(e1 @ e1)
    e2 = np.array([y * e1[2] - z * e1[1], z * e1[0] - x * e1[2], x * e1[1] - y * e1[0]])
    return e1, e2


def fit_conic_normalised(xy: np.ndarray) -> np.ndarray | None:
    """Least-squares (algebraic, Hartley-normalised) conic through points (N,2).

    Returns the symmetric 3x3 ``Q`` with ``[x y 1] Q [x y 1]^T = 0`` in the input coordinates,
    or None when there are fewer than 5 points.
    """
    xy = np.asarray(xy, float).reshape(-1, 2)
    xy = xy[np.isfinite(xy).all(axis=1)]
    if len(xy) < 5:
        return None
    m = xy.mean(axis=0)
    s = np.sqrt(2) / max(np.sqrt(((xy - m) ** 2).sum(axis=1)).mean(), 1e-12)
    x, y = ((xy - m) * s).T
    A = np.column_stack([x * x, x * y, y * y, x, y, np.ones_like(x)])
    _, _, vt = np.linalg.svd(A, full_matrices=False)
    a, b, c, d, e, f = vt[-1]
    Qn = np.array([[a, b / 2, d / 2], [b / 2, c, e / 2], [d / 2, e / 2, f]])
    T = np.array([[s, 0, -s * m[0]], [0, s, -s * m[1]], [0, 0, 1.0]])
    return T.T @ Qn @ T


def cone_from_conic(Q: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Axis ``w`` and half-angle ``a`` of a cone from its conic ``Q ~ cos^2(a) I - w w^T``.

    The eigenvector whose eigenvalue has the sign opposite to the other two is ``w``;
    ``tan^2(a) = -l_w / mean(l_1, l_2)``. Returns None if ``Q`` is not a real cone's conic.
    """
    lam, vec = np.linalg.eigh(Q)
    signs = np.sign(lam)
    if np.count_nonzero(signs > 0) == 2:
        i = int(np.argmin(lam))
    elif np.count_nonzero(signs < 0) == 2:
        lam, i = -lam, int(np.argmax(lam))
    else:
        return None
    others = np.delete(lam, i)
    tan2 = -lam[i] / others.mean()
    if not np.isfinite(tan2) or tan2 <= 0:
        return None
    w = vec[:, i] * (1 if vec[2, i] > 0 else -1)
    return w / np.linalg.norm(w), float(np.arctan(np.sqrt(tan2)))


def px_per_rad(cam: CameraModel, v: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Raw-pixel length of a unit angle step of each ray ``v`` (N,3) away from the axis ``w``."""
    c = v @ w
    t = c[:, None] * v - w[None, :]
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)
    dxy = np.einsum("nij,nj->ni", pi_jacobian(v), t)
    duv = np.einsum("nij,nj->ni", cam.distort_jacobian(v[:, :2] / v[:, 2:3]), dxy)
    return np.linalg.norm(duv, axis=1)


def _residuals(v, w, a, scale):
    ang = np.arccos(np.clip(v @ w, -1.0, 1.0))
    return scale * (ang - a), ang


def _ransac(v, scale, a_range, thr_px, rng, n_hyp=64, extra=()):
    """Best (w, a) among 3-point hypotheses and ``extra`` ones: the most points within
    ``thr_px``, ties broken by the truncated squared residual (MSAC), so that of two cones
    explaining as many points the tighter one wins."""
    n = len(v)
    idx = rng.integers(0, n, (n_hyp, 3))
    idx = idx[(idx[:, 0] != idx[:, 1]) & (idx[:, 0] != idx[:, 2]) & (idx[:, 1] != idx[:, 2])]
    v1, v2, v3 = v[idx[:, 0]], v[idx[:, 1]], v[idx[:, 2]]
    nrm = np.cross(v2 - v1, v3 - v1)
    ln = np.linalg.norm(nrm, axis=1)
    ok = ln > 1e-12
    nrm = nrm[ok] / ln[ok, None]
    nrm *= np.sign(np.einsum("ij,ij->i", nrm, v1[ok]))[:, None]
    a = np.arccos(np.clip(np.einsum("ij,ij->i", nrm, v1[ok]), -1, 1))
    hyps_w, hyps_a = list(nrm), list(a)
    for w_e, a_e in extra:
        hyps_w.append(w_e)
        hyps_a.append(a_e)
    W, A = np.array(hyps_w), np.array(hyps_a)
    keep = (A >= a_range[0]) & (A <= a_range[1]) & (W[:, 2] > 0)
    if not keep.any():
        return None
    W, A = W[keep], A[keep]
    ang = np.arccos(np.clip(v @ W.T, -1, 1))  # (N,H)
    r2 = np.minimum((scale[:, None] * (ang - A[None, :])) ** 2, thr_px ** 2)
    b = int(np.argmin(r2.sum(axis=0)))
    return W[b], float(A[b])


def _start(cam, xy, v, a_range_rad, inlier_px, rng, n_hyp=64):
    """RANSAC start, with the algebraic conic fit and the mean ray as extra hypotheses."""
    extra = []
    Q = fit_conic_normalised(xy)
    if Q is not None:
        c = cone_from_conic(Q)
        if c is not None:
            extra.append(c)
    m = v.mean(axis=0)  # for evenly spread points, mean ray = cos(a) w
    if np.linalg.norm(m) > 0:
        w0 = m / np.linalg.norm(m)
        extra.append((w0, float(np.median(np.arccos(np.clip(v @ w0, -1, 1))))))
    scale0 = px_per_rad(cam, v, extra[-1][0]) if extra else np.full(len(v), cam.fx)
    return _ransac(v, scale0, a_range_rad, max(inlier_px, 2.0), rng, n_hyp=n_hyp, extra=extra)


def _irls(cam, v, w, a, inlier_px, max_iter, tight: bool):
    """Reweighted Gauss-Newton from (w, a); returns (w, a, inlier band px) or None.

    The band starts at ``max(inlier_px, 2)`` px and then follows 3.5 x the inliers' spread;
    with ``tight`` it never widens again (a start pulled off the outline by edges of things
    touching the sphere must not let those edges in)."""
    thr = max(inlier_px, 2.0)
    for it in range(max_iter):
        if it in (0, 3):  # the px-per-radian scale barely moves once w is close
            scale = px_per_rad(cam, v, w)
        r, ang = _residuals(v, w, a, scale)
        inl = np.abs(r) < thr
        if inl.sum() < 6:
            return None
        ri = r[inl]
        # spread of the points already inside the band (mean absolute deviation x 1.2533 is
        # sigma for Gaussian noise; cheaper than a median and robust enough after the band)
        sig = 1.2533 * float(np.abs(ri - ri.mean()).mean())
        # Huber weights (k = 1.345 sigma) inside the inlier band, 0 outside; points inside the
        # cone (r < 0) fall off faster: a silhouette can only lose outline (gaps between the
        # wires of an open mesh, occlusion), never gain any beyond the sphere
        k = max(1.345 * max(sig, 0.05), 0.1)
        ar = np.maximum(np.abs(r), 1e-12)
        wt = np.where(r >= 0, np.minimum(1.0, k / ar), np.minimum(1.0, (k / ar) ** 2))
        wt = np.where(inl, wt, 0.0)
        e1, e2 = orthonormal_basis(w)
        sin_ang = np.maximum(np.sin(ang), 1e-9)
        J = np.column_stack([-scale * (v @ e1) / sin_ang, -scale * (v @ e2) / sin_ang, -scale])
        JW = J * wt[:, None]
        step = np.linalg.solve(JW.T @ J + 1e-12 * np.eye(3), -(JW.T @ r))
        w = w + step[0] * e1 + step[1] * e2
        w /= np.linalg.norm(w)
        a = a + step[2]
        if it >= 2:
            thr = min(thr, max(inlier_px, 3.5 * sig)) if tight else max(inlier_px, 3.5 * sig)
        if np.abs(step).max() < 1e-8 and it >= 4:
            break
    return w, a, thr


def _finish(cam, v, w, a, thr, corr_points) -> ConeFit | None:
    """Inliers, robust spread and parameter covariance at the solution."""
    scale = px_per_rad(cam, v, w)
    r, ang = _residuals(v, w, a, scale)
    inl = np.abs(r) < thr
    if inl.sum() < 6:
        return None
    e1, e2 = orthonormal_basis(w)
    sin_ang = np.maximum(np.sin(ang[inl]), 1e-9)
    J = np.column_stack([-scale[inl] * (v[inl] @ e1) / sin_ang, -scale[inl] * (v[inl] @ e2) / sin_ang,
                         -scale[inl]])
    dof = max(int(inl.sum()) - 3, 1)
    sig2 = float((r[inl] ** 2).sum() / dof)
    try:
        cov = sig2 * max(corr_points, 1.0) * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        return None
    sig_rob = 1.4826 * float(np.median(np.abs(r[inl] - np.median(r[inl]))))
    return ConeFit(w=w, a_rad=float(a), inliers=inl, residuals_px=r, sigma_px=sig_rob,
                   cov_params=cov, basis=np.vstack([w, e1, e2]))


def fit_cone(cam: CameraModel, xy: np.ndarray, a_range_rad=(1e-3, 1.4), inlier_px: float = 1.5,
             rng: np.random.Generator | None = None, corr_points: float = 1.0,
             start: tuple[np.ndarray, float] | None = None, max_iter: int = 12,
             tight: bool = False, n_hyp: int = 64) -> ConeFit | None:
    """Robust fit of a sphere's silhouette cone to edge points.

    Args:
        cam: camera model (for the px-per-radian scale of each residual).
        xy: (N,2) edge points in normalised undistorted coordinates (``cam.normalize(uv_px)``).
        a_range_rad: plausible half-angles (from the known radius and the range limits).
        inlier_px: residual (raw px) beyond which a point is an outlier (chain, texture, clutter).
        rng: random generator for the 3-point RANSAC start.
        corr_points: how many neighbouring edge points share one independent error (the
            edge samples are closer than the smoothing length); inflates the covariance.
        start: (w, a_rad) of a previous fit; skips the RANSAC start.
        max_iter: most reweighted Gauss-Newton steps.
        tight: the inlier band only narrows during the iterations (see :func:`_irls`).
        n_hyp: 3-point hypotheses of the RANSAC start (more where few points are on the outline).

    Returns:
        :class:`ConeFit`, or None when no plausible cone explains the points.
    """
    rng = rng or np.random.default_rng(0)
    xy = np.asarray(xy, float).reshape(-1, 2)
    if not np.isfinite(xy).all():
        return None
    v = rays_from_xy(xy)
    if len(v) < 8:
        return None
    if start is None:
        start = _start(cam, xy, v, a_range_rad, inlier_px, rng, n_hyp)
        if start is None:
            return None
    out = _irls(cam, v, np.asarray(start[0], float), float(start[1]), inlier_px, max_iter, tight)
    if out is None:
        return None
    w, a, thr = out
    if not (a_range_rad[0] <= a <= a_range_rad[1]) or w[2] <= 0:
        return None
    return _finish(cam, v, w, a, thr, corr_points)


def centre_uv_and_cov(cam: CameraModel, fit: ConeFit) -> tuple[np.ndarray, np.ndarray]:
    """Raw pixel of the sphere centre's projection (2,) and its covariance (2,2) in px^2."""
    w, e1, e2 = fit.basis
    uv = cam.project(w[None, :])[0]
    Jproj = cam.project_jacobian(w[None, :])[0]  # d uv / d X at X = w
    G = np.column_stack([Jproj @ e1, Jproj @ e2, np.zeros(2)])
    return uv, G @ fit.cov_params @ G.T


def silhouette_uv(cam: CameraModel, w: np.ndarray, a_rad: float, n: int = 180,
                  offset_rad: float = 0.0) -> np.ndarray:
    """Raw-pixel points (n,2) of the cone of axis ``w`` and half-angle ``a_rad + offset_rad``.

    Rays behind the camera give NaN rows.
    """
    e1, e2 = orthonormal_basis(w)
    phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
    a = a_rad + offset_rad
    v = np.cos(a) * w[None, :] + np.sin(a) * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
    return cam.project(v)


def normalize_near(cam: CameraModel, uv_px: np.ndarray, xy_start: np.ndarray | None = None,
                   iterations: int = 6) -> np.ndarray:
    """``cam.normalize`` for points with a good start: Newton steps on the exact forward model.

    Starts from ``xy_start`` (N,2) (default: the pinhole guess K^-1 uv); points whose
    reprojection is not within 1e-6 px after the steps go through ``cam.normalize``. Much
    cheaper than OpenCV's fixed-point iterations for the few hundred edge points per fit.
    """
    uv = np.asarray(uv_px, float).reshape(-1, 2)
    if xy_start is None:
        xy = np.column_stack([(uv[:, 0] - cam.cx - cam.K[0, 1] * (uv[:, 1] - cam.cy) / cam.fy) / cam.fx,
                              (uv[:, 1] - cam.cy) / cam.fy])
    else:
        xy = np.array(xy_start, float).reshape(-1, 2)
    with np.errstate(all="ignore"):
        for _ in range(iterations):
            r = cam.distort(xy) - uv
            J = cam.distort_jacobian(xy)
            det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
            xy = xy - np.column_stack([J[:, 1, 1] * r[:, 0] - J[:, 0, 1] * r[:, 1],
                                       -J[:, 1, 0] * r[:, 0] + J[:, 0, 0] * r[:, 1]]) / det[:, None]
            if np.abs(r).max(initial=0.0) < 1e-9:
                break
        bad = ~(np.abs(cam.distort(xy) - uv) < 1e-6).all(axis=1)
    if bad.any():
        xy[bad] = cam.normalize(uv[bad])
    return xy


def silhouette_xy(w: np.ndarray, a_rad: float, n: int) -> np.ndarray:
    """Normalised undistorted points (n,2) of the cone of axis ``w`` (w_z > 0 assumed)."""
    e1, e2 = orthonormal_basis(w)
    phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
    v = np.cos(a_rad) * w[None, :] + np.sin(a_rad) * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
    with np.errstate(all="ignore"):
        return v[:, :2] / v[:, 2:3]
