"""A camera's outline bias, estimated with the range scale from the sphere's apparent size.

An image range is ``R / sin(a)`` with ``a`` the half-angle of the silhouette cone the image
detector fits. Blur through the camera's gamma curve, JPEG and limb shading move the whole
outline of a ball outwards (or inwards) by about the same number of pixels ``b`` on every
capture of a camera. The detector's cone fit weighs each outline point's angle by its pixels
per radian (:func:`calib_core.detect.image.cone.px_per_rad`), so the fitted half-angle is

    a_obs = a + beta * b,    beta = mean over the outline of 1 / (px per radian)

(about ``1 / f`` near the image centre, less off-axis). The range the camera reports is then
``R / sin(a + beta b)``: relatively ``b d / (f R)`` short, an error that grows with the range,
while a sound-speed error ``s`` is the same ratio at every range. With apparent radii that vary
across captures the two are told apart; ``b`` is a parameter of the fit with a Gaussian prior
of the stated outline tolerance (``sphere.outline_sigma_px``), so when the radii do not vary
enough the prior, not the data, bounds it and the scale's sigma carries it (what a fixed
systematic would give).

:class:`OutlineRangeProblem` is a one-camera :class:`RigProblem` with ranges whose parameters
are the pose, then ``b`` (px), then the scale when estimated (the scale stays last).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from calib_core.solve.model import CameraData, RigState
from calib_core.solve.refine import RigProblem

OUTLINE_INDEX = 6  # the outline bias's place among the parameters (after the pose)
# data that shrink the outline bias's sigma below this share of its prior have separated it
# from the scale; above it the prior decides (said in the note)
SEPARATED_SHARE = 0.5


@dataclass
class RangeModel:
    """How one camera's image ranges are modelled: the diameter's relative tolerance (a
    systematic common to every range), the sphere's radius, and the outline bias's prior sigma
    (px; 0 holds the bias at 0 and leaves the old fixed-systematic route)."""

    diameter_rel_sigma: float
    sphere_radius_m: float | None = None
    outline_sigma_px: float = 0.0

    @property
    def estimates_outline(self) -> bool:
        return self.sphere_radius_m is not None and self.sphere_radius_m > 0 and self.outline_sigma_px > 0


@dataclass
class OutlineState(RigState):
    """A rig state with the reference camera's outline bias (px, positive = outline outwards)."""

    outline_px: float = 0.0


def outline_gain(cd: CameraData, rows: np.ndarray, radius_m: float, n: int = 36) -> np.ndarray:
    """``beta`` per row (rad per px of outline bias): the mean of 1 / (px per radian) over the
    silhouette the camera saw (axis from the image centre, half-angle from the image range)."""
    from calib_core.detect.image.cone import orthonormal_basis, px_per_rad

    xy = cd.xy[rows]
    w_all = np.column_stack([xy, np.ones(len(xy))])
    w_all /= np.linalg.norm(w_all, axis=1, keepdims=True)
    a_all = np.arcsin(np.clip(radius_m / cd.range_m[rows], 0.0, 0.999))
    phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
    out = np.empty(len(rows))
    for i, (w, a) in enumerate(zip(w_all, a_all)):
        e1, e2 = orthonormal_basis(w)
        v = np.cos(a) * w[None] + np.sin(a) * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
        out[i] = float(np.mean(1.0 / px_per_rad(cd.cam, v, w)))
    return out


class OutlineRangeProblem(RigProblem):
    """One camera with image ranges and a free outline bias (see the module doc)."""

    def __init__(self, cd: CameraData, used: np.ndarray, radius_m: float, prior_sigma_px: float,
                 estimate_scale: bool = False):
        super().__init__([cd], [used], estimate_scale=estimate_scale, use_ranges=True)
        self.radius_m = float(radius_m)
        self.prior_sigma_px = float(prior_sigma_px)
        self.beta = outline_gain(cd, self.range_rows, self.radius_m)
        self.n_params += 1

    @property
    def n_residuals(self) -> int:
        return super().n_residuals + 1  # the prior row of the outline bias

    def param_names(self) -> list[str]:
        names = super().param_names()
        return names[:OUTLINE_INDEX] + [f"{self.names[0]}.outline_px"] + names[OUTLINE_INDEX:]

    def with_range_factor(self, factor: float) -> OutlineRangeProblem:
        """The same problem with every image range times ``factor`` (a diameter error)."""
        cd = dataclasses.replace(self.cams[0], range_m=self.cams[0].range_m * factor)
        return OutlineRangeProblem(cd, self.masks[0], self.radius_m, self.prior_sigma_px, self.estimate_scale)

    def apply(self, state: RigState, theta: np.ndarray) -> OutlineState:
        st = super().apply(state, np.delete(theta, OUTLINE_INDEX))
        return OutlineState(st.T_ref_sonar, st.T_cam_ref, st.scale, outline_of(state) + float(theta[OUTLINE_INDEX]))

    def _angles(self, state: RigState):
        """(predicted distance |P|, true half-angle, observed half-angle) of the range rows."""
        _, P = self._range_points(state)
        dist = np.linalg.norm(P, axis=1)
        a = np.arcsin(np.clip(self.radius_m / dist, 0.0, 0.999))
        return dist, a, a + self.beta * outline_of(state)

    def range_residuals(self, state: RigState) -> np.ndarray:
        _, _, a_obs = self._angles(state)
        return self.radius_m / np.sin(a_obs) - self.cams[0].range_m[self.range_rows]

    def _range_jacobian(self, st: RigState, theta: np.ndarray, w: np.ndarray) -> np.ndarray:
        J = super()._range_jacobian(st, theta, w)  # d|P| / d theta, weighted
        dist, a, a_obs = self._angles(st)
        dd_da = -self.radius_m * np.cos(a_obs) / np.sin(a_obs) ** 2
        da_ddist = -self.radius_m / (dist**2 * np.maximum(np.cos(a), 1e-9))
        J *= (dd_da * da_ddist)[:, None]
        J[:, OUTLINE_INDEX] = w * dd_da * self.beta
        return J

    def whitened(self, state: RigState, Ws: list[np.ndarray]) -> np.ndarray:
        return np.append(super().whitened(state, Ws), outline_of(state) / self.prior_sigma_px)

    def whitened_jacobian(self, state: RigState, theta: np.ndarray, Ws: list[np.ndarray]) -> np.ndarray:
        J = super().whitened_jacobian(state, theta, Ws)
        row = np.zeros((1, self.n_params))
        row[0, OUTLINE_INDEX] = 1.0 / self.prior_sigma_px
        return np.vstack([J, row])


def outline_of(state: RigState) -> float:
    return float(getattr(state, "outline_px", 0.0))


def with_outline(state: RigState, outline_px: float | None = None) -> OutlineState:
    """``state`` as an :class:`OutlineState` (keeping its outline bias unless one is given)."""
    b = outline_of(state) if outline_px is None else float(outline_px)
    return OutlineState(state.T_ref_sonar, dict(state.T_cam_ref), state.scale, b)


def outline_summary(problem: OutlineRangeProblem, res) -> dict:
    """The outline bias of a fit: value and sigma (px), the prior's sigma, the sigma the data alone
    give, whether the data separated it from the scale, and the spread of apparent radii (px)."""
    var = float(res.cov[OUTLINE_INDEX, OUTLINE_INDEX]) * max(1.0, res.variance_factor)
    sig = math.sqrt(max(var, 0.0))
    info_data = 1.0 / max(var, 1e-300) - 1.0 / problem.prior_sigma_px**2
    sig_data = 1.0 / math.sqrt(info_data) if info_data > 0 else math.inf
    cd = problem.cams[0]
    r_px = cd.cam.fx * problem.radius_m / cd.range_m[problem.range_rows]
    return {"value_px": outline_of(res.state), "sigma_px": sig, "prior_sigma_px": problem.prior_sigma_px,
            "data_sigma_px": sig_data, "separated": sig <= SEPARATED_SHARE * problem.prior_sigma_px,
            "apparent_radius_px": [float(r_px.min()), float(r_px.max())]}


def outline_phrase(name: str, o: dict) -> str:
    """One camera's outline bias, said once (the note of the range scale)."""
    lo, hi = o["apparent_radius_px"]
    head = f"{name} outline bias {o['value_px']:+.2f} ± {o['sigma_px']:.2f} px"
    if o["separated"]:
        return f"{head} (told apart from the scale by apparent radii {lo:.0f}-{hi:.0f} px)"
    alone = f"the data alone give ±{o['data_sigma_px']:.1f} px" if math.isfinite(o["data_sigma_px"]) else \
        "the data alone do not bound it"
    return (f"{head}: not told apart from the scale (apparent radii only {lo:.0f}-{hi:.0f} px; {alone}), so its "
            f"±{o['prior_sigma_px']:.1f} px tolerance limits the scale; captures over a wider range of distances "
            f"separate them")
