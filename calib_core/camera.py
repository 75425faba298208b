"""Camera model of the paper (eqs. 1-9): pinhole + plumb_bob distortion, OpenCV's
rational model (ROS ``rational_polynomial``: k4..k6 divide the radial polynomial), which
depth cameras such as the Azure Kinect publish, or OpenCV's fisheye model (ROS and Kalibr
``equidistant``: the distorted radius is a polynomial in the angle off the axis,
theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)), which wide-angle
and dome-port cameras are calibrated with.

Frames: points in the camera frame follow OpenCV (x right, y down, z forward), metres.
``xy`` are normalised undistorted coordinates (the paper's x', y'), ``uv_px`` raw
(distorted) pixel coordinates. The paper's ``P-hat`` is :meth:`CameraModel.distort`
and its inverse ``P-hat^-1`` is :meth:`CameraModel.normalize`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np


@dataclass(frozen=True)
class CameraModel:
    """Intrinsics of one camera.

    Attributes:
        width_px, height_px: image size.
        K: 3x3 camera matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] in pixels.
        dist: (k1, k2, p1, p2, k3), OpenCV order; or (k1, k2, p1, p2, k3, k4, k5, k6) for
            the rational model, kept only when k4..k6 are not all zero; or (k1, k2, k3, k4)
            of the fisheye model when ``fisheye``.
        name: camera name (free text).
        fisheye: OpenCV's fisheye (equidistant) model instead of plumb_bob / rational.
    """

    width_px: int
    height_px: int
    K: np.ndarray
    dist: np.ndarray = field(default_factory=lambda: np.zeros(5))
    name: str = ""
    fisheye: bool = False

    def __post_init__(self):
        object.__setattr__(self, "K", np.asarray(self.K, dtype=float).reshape(3, 3))
        dd = np.asarray(self.dist, dtype=float).ravel()
        if self.fisheye:
            d = np.zeros(4)
        else:
            d = np.zeros(8 if np.any(dd[5:8] != 0) else 5)
        d[: min(d.size, dd.size)] = dd[: d.size]
        object.__setattr__(self, "dist", d)
        object.__setattr__(self, "fisheye", bool(self.fisheye))

    @property
    def distortion_model(self) -> str:
        """The ROS name of the lens model: plumb_bob, rational_polynomial or equidistant."""
        return "equidistant" if self.fisheye else "rational_polynomial" if self.rational else "plumb_bob"

    @property
    def rational(self) -> bool:
        """True for OpenCV's rational model (8 coefficients, k4..k6 not all zero)."""
        return self.dist.size == 8 and not self.fisheye

    def _fisheye_scale(self, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fisheye: s(r) = theta_d / r for the undistorted radius r = |xy|, and s'(r) / r
        (both finite at r = 0, from their series there)."""
        k1, k2, k3, k4 = self.dist
        th = np.arctan(r)
        t2 = th * th
        poly = 1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)))
        dpoly = 1 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))  # d(theta_d)/d theta
        small = r < 1e-6
        rs = np.where(small, 1.0, r)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.where(small, 1.0, th * poly / rs)
            ds_over_r = (dpoly / (1 + rs * rs) * rs - th * poly) / rs**3
        # series at r -> 0: s = 1 + (k1 - 1/3) r^2 + ..., so s'(r)/r -> 2 (k1 - 1/3)
        return s, np.where(small, 2 * (k1 - 1.0 / 3.0), ds_over_r)

    def _radial(self, r2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Radial factor and its derivative with respect to r^2."""
        k1, k2, p1, p2, k3 = self.dist[:5]
        num = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
        dnum = k1 + 2 * k2 * r2 + 3 * k3 * r2**2
        if not self.rational:
            return num, dnum
        k4, k5, k6 = self.dist[5:]
        den = 1 + k4 * r2 + k5 * r2**2 + k6 * r2**3
        dden = k4 + 2 * k5 * r2 + 3 * k6 * r2**2
        with np.errstate(divide="ignore", invalid="ignore"):
            return num / den, (dnum * den - num * dden) / (den * den)

    @property
    def fx(self) -> float:
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        return float(self.K[1, 2])

    # ---- forward model -------------------------------------------------
    def distort(self, xy: np.ndarray) -> np.ndarray:
        """P-hat: normalised undistorted (N,2) -> raw pixels (N,2) (eqs. 5-8)."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        x, y = xy[:, 0], xy[:, 1]
        r2 = x * x + y * y
        if self.fisheye:
            s, _ = self._fisheye_scale(np.sqrt(r2))
            xd, yd = x * s, y * s
        else:
            p1, p2 = self.dist[2:4]
            radial, _ = self._radial(r2)
            xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
            yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        return np.column_stack([self.fx * xd + self.K[0, 1] * yd + self.cx, self.fy * yd + self.cy])

    def project(self, points_cam_m: np.ndarray) -> np.ndarray:
        """Project (N,3) camera-frame points (m) to raw pixels (N,2). Points with z<=0 give NaN."""
        P = np.asarray(points_cam_m, dtype=float).reshape(-1, 3)
        z = P[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = P[:, :2] / z[:, None]
        xy[z <= 0] = np.nan
        return self.distort(xy)

    # ---- inverse model -------------------------------------------------
    def normalize(self, uv_px: np.ndarray, iterations: int = 3) -> np.ndarray:
        """P-hat inverse: raw pixels (N,2) -> normalised undistorted (N,2).

        OpenCV's fixed-point undistortion (with many iterations) gives the start;
        damped Newton steps on the exact forward model (at least ``iterations``, more
        until converged) then bring the error to ~1e-9 px or below, also near the corners
        of strongly distorted images. Pixels the model cannot reach (beyond the fold of a
        strong radial distortion, where P-hat is not invertible) and NaN inputs give NaN.
        """
        uv = np.asarray(uv_px, dtype=float).reshape(-1, 2)
        if uv.shape[0] == 0:
            return uv.copy()
        finite = np.isfinite(uv).all(axis=1)
        xy = self._undistort_start(uv, finite)
        with np.errstate(all="ignore"):
            res = np.linalg.norm(self.distort(xy) - uv, axis=1)
            for it in range(max(iterations, 40)):
                if it >= iterations and not (res[finite] > 1e-10).any():
                    break
                self._newton_step(xy, uv, res)
            J = self.distort_jacobian(xy)
            det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
        # a root with det <= 0 lies beyond the fold of the radial polynomial: not a real view ray
        good = finite & (res < 1e-6) & (det > 0)
        xy[~good] = np.nan
        return xy

    def _undistort_start(self, uv: np.ndarray, finite: np.ndarray) -> np.ndarray:
        """Start for :meth:`normalize`: OpenCV's iterative undistortion, the pinhole inverse
        where that fails (non-finite or far off)."""
        xy = self.opencv_normalize(np.where(finite[:, None], uv, 0.0), 50)
        naive = np.column_stack([(uv[:, 0] - self.cx) / self.fx, (uv[:, 1] - self.cy) / self.fy])
        start_bad = ~np.isfinite(xy).all(axis=1) | (np.abs(xy) > 1e3).any(axis=1)
        xy[start_bad] = naive[start_bad]
        return xy

    def opencv_normalize(self, uv_px: np.ndarray, iterations: int) -> np.ndarray:
        """OpenCV's iterative undistortion of raw pixels (N,2) to normalised (N,2), for the
        lens model in use (``cv2.fisheye`` for the fisheye model): fast, approximate near
        strong distortion; :meth:`normalize` refines it."""
        src = np.ascontiguousarray(np.asarray(uv_px, dtype=float).reshape(-1, 1, 2))
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, int(iterations), 1e-12)
        if self.fisheye:
            xy = cv2.fisheye.undistortPoints(src, self.K, self.dist, criteria=crit)
        elif hasattr(cv2, "undistortPointsIter"):  # OpenCV 4.x
            xy = cv2.undistortPointsIter(src, self.K, self.dist, None, None, crit)
        else:  # OpenCV 5 folded the criteria into undistortPoints
            xy = cv2.undistortPoints(src, self.K, self.dist, None, None, None, crit)
        return xy.reshape(-1, 2).astype(float)

    def _newton_step(self, xy: np.ndarray, uv: np.ndarray, res: np.ndarray) -> None:
        """One damped Newton step of :meth:`normalize` (``xy`` and its pixel error ``res`` in
        place): halved up to 8 times where the full step makes the error worse."""
        r = self.distort(xy) - uv
        J = self.distort_jacobian(xy)  # (N,2,2) d uv / d xy
        det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
        step = np.column_stack([J[:, 1, 1] * r[:, 0] - J[:, 0, 1] * r[:, 1],
                                -J[:, 1, 0] * r[:, 0] + J[:, 0, 0] * r[:, 1]]) / det[:, None]
        step[~np.isfinite(step)] = 0.0
        scale = np.ones(len(xy))
        for _ in range(8):  # backtrack where a full step makes things worse
            trial = xy - scale[:, None] * step
            new_res = np.linalg.norm(self.distort(trial) - uv, axis=1)
            worse = ~(new_res <= res)
            if not worse.any():
                break
            scale[worse] *= 0.5
        ok = new_res <= res
        xy[ok] = trial[ok]
        res[ok] = new_res[ok]

    def rays(self, uv_px: np.ndarray) -> np.ndarray:
        """Unit viewing rays (N,3) in the camera frame for raw pixels (N,2). A fisheye's rays
        may look 90 deg or more off the axis (z <= 0), where normalised coordinates end."""
        if self.fisheye:
            return self._fisheye_rays(uv_px)
        xy = self.normalize(uv_px)
        v = np.column_stack([xy, np.ones(len(xy))])
        return v / np.linalg.norm(v, axis=1, keepdims=True)

    def _fisheye_rays(self, uv_px: np.ndarray) -> np.ndarray:
        """:meth:`rays` of the fisheye model: theta from theta_d by Newton on the polynomial;
        NaN beyond its fold (where theta_d stops growing with theta) and for NaN input."""
        uv = np.asarray(uv_px, dtype=float).reshape(-1, 2)
        yd = (uv[:, 1] - self.cy) / self.fy
        xd = (uv[:, 0] - self.cx - self.K[0, 1] * yd) / self.fx
        rd = np.hypot(xd, yd)
        k = self.dist
        th = np.clip(rd, 0.0, np.pi)
        with np.errstate(all="ignore"):
            for _ in range(30):
                t2 = th * th
                f = th * (1 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3])))) - rd
                df = 1 + t2 * (3 * k[0] + t2 * (5 * k[1] + t2 * (7 * k[2] + t2 * 9 * k[3])))
                th = np.clip(th - f / df, 0.0, np.pi)
            ok = (np.abs(f) < 1e-9) & (df > 0)
            s = np.where(rd > 1e-12, np.sin(th) / np.where(rd > 1e-12, rd, 1.0), 1.0)
        v = np.column_stack([xd * s, yd * s, np.cos(th)])
        v[~ok] = np.nan
        return v

    # ---- Jacobians -----------------------------------------------------
    def distort_jacobian(self, xy: np.ndarray) -> np.ndarray:
        """d uv_px / d xy, shape (N,2,2), at normalised undistorted points."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        x, y = xy[:, 0], xy[:, 1]
        r2 = x * x + y * y
        if self.fisheye:
            s, ds_over_r = self._fisheye_scale(np.sqrt(r2))
            dxd_dx, dxd_dy = s + x * x * ds_over_r, x * y * ds_over_r
            dyd_dx, dyd_dy = dxd_dy, s + y * y * ds_over_r
        else:
            p1, p2 = self.dist[2:4]
            radial, dradial_dr2 = self._radial(r2)
            dxd_dx = radial + x * dradial_dr2 * 2 * x + 2 * p1 * y + p2 * 6 * x
            dxd_dy = x * dradial_dr2 * 2 * y + 2 * p1 * x + p2 * 2 * y
            dyd_dx = y * dradial_dr2 * 2 * x + p1 * 2 * x + 2 * p2 * y
            dyd_dy = radial + y * dradial_dr2 * 2 * y + p1 * 6 * y + 2 * p2 * x
        J = np.empty((len(x), 2, 2))
        J[:, 0, 0] = self.fx * dxd_dx + self.K[0, 1] * dyd_dx
        J[:, 0, 1] = self.fx * dxd_dy + self.K[0, 1] * dyd_dy
        J[:, 1, 0] = self.fy * dyd_dx
        J[:, 1, 1] = self.fy * dyd_dy
        return J

    def project_jacobian(self, points_cam_m: np.ndarray) -> np.ndarray:
        """d uv_px / d X_cam, shape (N,2,3), for camera-frame points (m)."""
        P = np.asarray(points_cam_m, dtype=float).reshape(-1, 3)
        return self.distort_jacobian(P[:, :2] / P[:, 2:3]) @ pi_jacobian(P)

    # ---- convenience ---------------------------------------------------
    def in_image(self, uv_px: np.ndarray, margin_px: float = 0.0) -> np.ndarray:
        """Boolean mask of pixels inside the image (with an optional margin)."""
        uv = np.asarray(uv_px, dtype=float).reshape(-1, 2)
        return (
            np.isfinite(uv).all(axis=1)
            & (uv[:, 0] >= -0.5 + margin_px)
            & (uv[:, 0] <= self.width_px - 0.5 - margin_px)
            & (uv[:, 1] >= -0.5 + margin_px)
            & (uv[:, 1] <= self.height_px - 0.5 - margin_px)
        )


def vertical_fov_rad(cam: CameraModel) -> float:
    """The vertical field of view (rad): the angles off the optical axis of the rays through the
    top and bottom edge centres, added (a fisheye's may pass 180 deg); for a principal point
    inside the image. Where a fisheye's edge ray is beyond its lens's fold: f theta's h / fy."""
    ends = np.array([[cam.cx, -0.5], [cam.cx, cam.height_px - 0.5]])
    v = cam.rays(ends)
    if not np.isfinite(v).all():
        return float(cam.height_px / cam.fy if cam.fisheye else 2 * np.arctan(cam.height_px / (2 * cam.fy)))
    return float(np.sum(np.arccos(np.clip(v[:, 2], -1.0, 1.0))))


def distortion_terms(cam: CameraModel) -> str:
    """The names of ``cam.dist``'s values, in order, as every shell shows them."""
    if cam.fisheye:
        return "equidistant k1 k2 k3 k4"
    return "k1 k2 p1 p2 k3 k4 k5 k6" if cam.rational else "k1 k2 p1 p2 k3"


def pi_jacobian(points_cam_m: np.ndarray) -> np.ndarray:
    """d (X/Z, Y/Z) / d X_cam, shape (N,2,3): the Jacobian of the paper's pi()."""
    P = np.asarray(points_cam_m, dtype=float).reshape(-1, 3)
    z = P[:, 2]
    J = np.zeros((len(P), 2, 3))
    J[:, 0, 0] = 1 / z
    J[:, 1, 1] = 1 / z
    J[:, 0, 2] = -P[:, 0] / z**2
    J[:, 1, 2] = -P[:, 1] / z**2
    return J
