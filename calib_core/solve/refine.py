"""Maximum-likelihood refinement of a camera (or a rig of cameras) to the sonar.

Minimises the paper's eq. 15 residuals in normalised image coordinates, each capture
whitened by the Cholesky factor of its covariance (image covariance mapped to normalised
coordinates plus the sonar centre covariance propagated through the projection; see
:mod:`calib_core.solve.model`). The weights depend on the pose, so they are refreshed in an
outer loop until the solution stops moving (the usual "effective variance" form of the
errors-in-variables ML estimate; to first order it is the exact ML estimate with the true
centres as nuisance parameters, and its covariance is the Cramer-Rao bound's).

Parameters (all perturbations about the current state, so the covariance is that of the
perturbation at the optimum): reference camera rotation vector (rad, left-multiplied, so in
the camera frame) and translation (m); for each other camera tied to the reference by a
stereo transform with a covariance, the same six numbers for ``T_cam_ref`` (with a prior
residual pulling it to the measured stereo transform); optionally the range scale ``s``.
An optional robust loss (Huber or Cauchy on each capture's Mahalanobis distance) is applied
by iteratively reweighting.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_core.camera import pi_jacobian
from calib_core.solve.lm import levenberg_marquardt
from calib_core.solve.model import (MIN_DEPTH_M, CameraData, RigState, build_groups, exp_so3, group_covariance,
                                    log_so3, mahalanobis2, project_group, whitening)

ROBUST_LOSSES = ("huber", "cauchy")


@dataclass
class Link:
    """A camera tied to the reference camera: measured ``T_cam_ref`` and its 6x6 covariance
    (rotation vector rad, translation m), or None to hold it fixed."""

    T_cam_ref: np.ndarray
    cov: np.ndarray | None = None


class RigProblem:
    """Correspondences of one or more cameras (cams[0] is the reference) and how they are tied."""

    def __init__(self, cams: list[CameraData], masks: list[np.ndarray] | None = None,
                 links: dict[str, Link] | None = None, estimate_scale: bool = False, use_ranges: bool = False):
        self.cams = cams
        self.names = [c.name for c in cams]
        self.masks = [np.ones(len(c), bool) if masks is None else np.asarray(masks[i], bool) for i, c in enumerate(cams)]
        self.links = links or {}
        missing = [n for n in self.names[1:] if n not in self.links]
        if missing:
            raise ValueError(f"cameras {missing} are not tied to the reference camera {self.names[0]}")
        self.estimate_scale = estimate_scale
        self.groups = build_groups(cams, self.masks)
        self.free_links = [n for n in self.names[1:] if self.links[n].cov is not None]
        self._prior_W = {n: np.linalg.inv(np.linalg.cholesky(self.links[n].cov)) for n in self.free_links}
        self.n_params = 6 + 6 * len(self.free_links) + (1 if estimate_scale else 0)
        # camera ranges (sphere's apparent size) of the reference camera's used rows
        self.range_rows = np.flatnonzero(cams[0].range_mask(self.masks[0])) if use_ranges else np.zeros(0, int)
        if use_ranges and not len(self.range_rows):
            raise ValueError("use_ranges needs a range on a used row of the reference camera")

    @property
    def n_captures(self) -> int:
        return sum(len(g.ids) for g in self.groups)

    @property
    def n_residuals(self) -> int:
        return sum(2 * len(g.ids) * len(g.cams) for g in self.groups) + 6 * len(self.free_links) + len(self.range_rows)

    def param_names(self) -> list[str]:
        names = [f"{self.names[0]}.{a}" for a in ("rx", "ry", "rz", "tx", "ty", "tz")]
        for n in self.free_links:
            names += [f"{n}/{self.names[0]}.{a}" for a in ("rx", "ry", "rz", "tx", "ty", "tz")]
        return names + (["scale"] if self.estimate_scale else [])

    def apply(self, state: RigState, theta: np.ndarray) -> RigState:
        """The state moved by a parameter perturbation ``theta``."""
        T = state.T_ref_sonar.copy()
        T[:3, :3] = exp_so3(theta[0:3]) @ T[:3, :3]
        T[:3, 3] = T[:3, 3] + theta[3:6]
        links = dict(state.T_cam_ref)
        for i, n in enumerate(self.free_links):
            d = theta[6 + 6 * i: 12 + 6 * i]
            L = links[n].copy()
            L[:3, :3] = exp_so3(d[:3]) @ L[:3, :3]
            L[:3, 3] = L[:3, 3] + d[3:]
            links[n] = L
        s = state.scale + (theta[-1] if self.estimate_scale else 0.0)
        return RigState(T, links, s)

    def poses(self, state: RigState) -> list[np.ndarray]:
        return [state.T_cam_sonar(n) for n in self.names]

    def group_terms(self, state: RigState):
        """Per group: stacked residual (G,2k), covariance S (G,2k,2k), camera points (G,k,3)."""
        Ts = self.poses(state)
        out = []
        for g in self.groups:
            pred, P, J = project_group(g, Ts, state.scale)
            r = (pred - g.xy).reshape(len(g.ids), -1)
            out.append((r, group_covariance(g, J), P))
        return out

    def prior_residuals(self, state: RigState) -> np.ndarray:
        res = []
        for n in self.free_links:
            meas = self.links[n].T_cam_ref
            cur = state.T_cam_ref[n]
            e = np.concatenate([log_so3(cur[:3, :3] @ meas[:3, :3].T), cur[:3, 3] - meas[:3, 3]])
            res.append(self._prior_W[n] @ e)
        return np.concatenate(res) if res else np.zeros(0)

    def whitened(self, state: RigState, Ws: list[np.ndarray]) -> np.ndarray:
        Ts = self.poses(state)
        parts = []
        for g, W in zip(self.groups, Ws):
            pred, _, _ = project_group(g, Ts, state.scale)
            r = (pred - g.xy).reshape(len(g.ids), -1)
            parts.append(np.einsum("gij,gj->gi", W, r).ravel())
        parts.append(self.prior_residuals(state))
        if len(self.range_rows):
            parts.append(Ws[-1] * self.range_residuals(state))
        return np.concatenate(parts)

    def _range_points(self, state: RigState):
        """Reference-camera points of the range rows: (sonar points rotated and rescaled, camera points)."""
        cd = self.cams[0]
        T = state.T_ref_sonar
        RX = cd.X_sonar_m[self.range_rows] @ T[:3, :3].T / state.scale
        return RX, RX + T[:3, 3]

    def range_residuals(self, state: RigState) -> np.ndarray:
        """Predicted minus measured camera range (m) of every range row."""
        _, P = self._range_points(state)
        return np.linalg.norm(P, axis=1) - self.cams[0].range_m[self.range_rows]

    def range_weights(self, state: RigState) -> np.ndarray:
        """1 / sigma of each range residual: the range's own sigma and the sonar centre's covariance
        along the camera ray (its cross-covariance with the image residual is neglected: it vanishes
        for an isotropic sonar covariance, since the image does not see motion along the ray)."""
        cd = self.cams[0]
        _, P = self._range_points(state)
        u = P / np.linalg.norm(P, axis=1, keepdims=True)
        A = state.T_ref_sonar[:3, :3] / state.scale
        C = A @ cd.cov_X_m2[self.range_rows] @ A.T
        var = cd.range_sigma_m[self.range_rows] ** 2 + np.einsum("ni,nij,nj->n", u, C, u)
        return 1.0 / np.sqrt(var)

    def _range_jacobian(self, st: RigState, theta: np.ndarray, w: np.ndarray) -> np.ndarray:
        RX, P = self._range_points(st)
        u = P / np.linalg.norm(P, axis=1, keepdims=True)
        J = np.zeros((len(P), self.n_params))
        J[:, 0:3] = -np.einsum("ni,nij->nj", u, skew_batch(RX)) @ left_jacobian(theta[0:3])
        J[:, 3:6] = u
        if self.estimate_scale:
            J[:, -1] = -np.sum(u * RX, axis=1) / st.scale
        return w[:, None] * J

    def whitened_jacobian(self, state: RigState, theta: np.ndarray, Ws: list[np.ndarray]) -> np.ndarray:
        """Analytic d whitened() / d theta at ``apply(state, theta)`` (prior rows by central differences)."""
        n = self.n_params
        st = self.apply(state, theta)
        R0, t0 = st.T_ref_sonar[:3, :3], st.T_ref_sonar[:3, 3]
        Jl0 = left_jacobian(theta[0:3])
        blocks = []
        for g, W in zip(self.groups, Ws):
            G, k = len(g.ids), len(g.cams)
            RX = g.X @ R0.T / st.scale  # (G,3) rotated, rescaled sonar points in the reference frame
            Q = RX + t0
            D = np.zeros((G, k, 2, n))
            for j, ci in enumerate(g.cams):
                dP = np.zeros((G, 3, n))
                name = self.names[ci]
                if ci == 0:
                    A, P = np.eye(3), Q
                else:
                    A = st.T_cam_ref[name][:3, :3]
                    P = Q @ A.T + st.T_cam_ref[name][:3, 3]
                dP[:, :, 0:3] = -(A @ skew_batch(RX)) @ Jl0
                dP[:, :, 3:6] = A
                if name in self.free_links:
                    i = 6 + 6 * self.free_links.index(name)
                    dP[:, :, i:i + 3] = -skew_batch(Q @ A.T) @ left_jacobian(theta[i:i + 3])
                    dP[:, :, i + 3:i + 6] = np.eye(3)
                if self.estimate_scale:
                    dP[:, :, -1] = -(RX @ A.T) / st.scale
                Pz = P.copy()
                Pz[:, 2] = np.maximum(P[:, 2], MIN_DEPTH_M)
                D[:, j] = pi_jacobian(Pz) @ dP
            blocks.append((W @ D.reshape(G, 2 * k, n)).reshape(-1, n))
        for i_link, name in enumerate(self.free_links):
            i = 6 + 6 * i_link
            meas = self.links[name].T_cam_ref
            e = log_so3(st.T_cam_ref[name][:3, :3] @ meas[:3, :3].T)
            Jp = np.zeros((6, n))
            Jp[:3, i:i + 3] = np.linalg.solve(left_jacobian(e), left_jacobian(theta[i:i + 3]))
            Jp[3:, i + 3:i + 6] = np.eye(3)
            blocks.append(self._prior_W[name] @ Jp)
        if len(self.range_rows):
            blocks.append(self._range_jacobian(st, theta, Ws[-1]))
        return np.vstack(blocks)


def skew_batch(v: np.ndarray) -> np.ndarray:
    """(G,3,3) cross-product matrices of (G,3) vectors."""
    S = np.zeros((len(v), 3, 3))
    S[:, 0, 1], S[:, 0, 2] = -v[:, 2], v[:, 1]
    S[:, 1, 0], S[:, 1, 2] = v[:, 2], -v[:, 0]
    S[:, 2, 0], S[:, 2, 1] = -v[:, 1], v[:, 0]
    return S


def left_jacobian(omega: np.ndarray) -> np.ndarray:
    """SO(3) left Jacobian: Exp(omega + d) = Exp(J_l d) Exp(omega) to first order."""
    w = np.asarray(omega, float)
    th2 = float(w @ w)
    Wx = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if th2 < 1e-10:
        return np.eye(3) + 0.5 * Wx + Wx @ Wx / 6.0
    th = np.sqrt(th2)
    return np.eye(3) + (1 - np.cos(th)) / th2 * Wx + (th - np.sin(th)) / (th2 * th) * (Wx @ Wx)


def irls_weights(m2: np.ndarray, loss: str | None, k: float) -> np.ndarray:
    """Per-capture weights from Mahalanobis^2 for a robust loss (1 everywhere for none)."""
    if loss is None:
        return np.ones_like(m2)
    m = np.sqrt(np.maximum(m2, 0))
    if loss == "huber":
        return np.where(m <= k, 1.0, k / np.maximum(m, 1e-12))
    if loss == "cauchy":
        return 1.0 / (1.0 + (m / k) ** 2)
    raise ValueError(f"robust loss must be one of {ROBUST_LOSSES} or None, got {loss!r}")


@dataclass
class RefineResult:
    """Outcome of :func:`refine`.

    Attributes:
        state: the optimum.
        cov: (n,n) covariance of the parameter perturbation at the optimum (see module doc), not
            scaled by the variance factor.
        param_names: names of the parameters (rotation rad, translation m, scale).
        chi2: sum of squared whitened residuals (robust weights included); dof: residuals - params.
        weights: per-capture robust weights per group (all ones without a robust loss).
        n_outer: weight refreshes used; converged: whether the last step was negligible.
        information_eigmin: smallest eigenvalue of the scaled information matrix (near 0 = a
            direction the data cannot see).
    """

    state: RigState
    cov: np.ndarray
    param_names: list[str]
    chi2: float
    dof: int
    weights: list[np.ndarray]
    n_outer: int
    converged: bool
    information_eigmin: float

    @property
    def variance_factor(self) -> float:
        return self.chi2 / self.dof if self.dof > 0 else float("nan")


def weights_for(problem: RigProblem, state: RigState, loss: str | None, k: float):
    """Per group: whitening matrices (robust weights folded in) and the robust weights, at ``state``."""
    Ws, ws = [], []
    for r, S, _ in problem.group_terms(state):
        w = irls_weights(mahalanobis2(r, S), loss, k)
        Ws.append(whitening(S) * np.sqrt(w)[:, None, None])
        ws.append(w)
    if len(problem.range_rows):
        Ws.append(problem.range_weights(state))
    return Ws, ws


def jacobian(problem: RigProblem, state: RigState, Ws) -> np.ndarray:
    """Jacobian of the whitened residuals w.r.t. the perturbation at 0."""
    return problem.whitened_jacobian(state, np.zeros(problem.n_params), Ws)


def covariance_from_jacobian(J: np.ndarray) -> tuple[np.ndarray, float]:
    """(J^T J)^-1 and the smallest eigenvalue of the diagonally scaled J^T J.

    A (near-)singular information matrix means some parameter combination is not observable;
    the pseudo-inverse is returned then and the caller decides what to say."""
    F = J.T @ J
    d = np.sqrt(np.maximum(np.diag(F), 1e-300))
    Fn = F / np.outer(d, d)
    eigmin = float(np.linalg.eigvalsh(Fn).min())
    cov = np.linalg.pinv(F, rcond=1e-14) if eigmin < 1e-12 else np.linalg.inv(F)
    return 0.5 * (cov + cov.T), eigmin


def refine(problem: RigProblem, state0: RigState, robust: str | None = None, robust_k: float = 2.5,
           max_outer: int = 12, step_tol: float = 1e-9) -> RefineResult:
    """Maximum-likelihood refinement from ``state0`` (see the module doc)."""
    if problem.n_residuals < problem.n_params:
        raise ValueError("fewer residuals than parameters")
    state = state0
    converged = False
    n_outer = 0
    for n_outer in range(1, max_outer + 1):
        Ws, ws = weights_for(problem, state, robust, robust_k)
        sol = levenberg_marquardt(lambda th: problem.whitened(problem.apply(state, th), Ws),
                                  lambda th: problem.whitened_jacobian(state, th, Ws), np.zeros(problem.n_params),
                                  xtol=1e-14, ftol=1e-14, gtol=1e-14, max_nfev=200 * problem.n_params)
        state = problem.apply(state, sol.x)
        if np.max(np.abs(sol.x)) < step_tol and n_outer > 1:
            converged = True
            break
    Ws, ws = weights_for(problem, state, robust, robust_k)
    r = problem.whitened(state, Ws)
    J = jacobian(problem, state, Ws)
    cov, eigmin = covariance_from_jacobian(J)
    return RefineResult(state, cov, problem.param_names(), float(r @ r), problem.n_residuals - problem.n_params,
                        ws, n_outer, converged, eigmin)


def pose_covariance(problem: RigProblem, res: RefineResult, cam: str, h: float = 1e-7,
                    with_scale: bool = False) -> np.ndarray:
    """6x6 covariance (rotation vector rad in the camera frame, translation m) of ``T_cam_sonar``;
    7x7 with the range scale appended when ``with_scale`` (and the scale was estimated)."""
    T0 = res.state.T_cam_sonar(cam)
    n = problem.n_params
    Jp = np.zeros((6, n))
    for i in range(n):
        d = np.zeros(n)
        d[i] = h
        Tp = problem.apply(res.state, d).T_cam_sonar(cam)
        Tm = problem.apply(res.state, -d).T_cam_sonar(cam)
        ep = np.concatenate([log_so3(Tp[:3, :3] @ T0[:3, :3].T), Tp[:3, 3] - T0[:3, 3]])
        em = np.concatenate([log_so3(Tm[:3, :3] @ T0[:3, :3].T), Tm[:3, 3] - T0[:3, 3]])
        Jp[:, i] = (ep - em) / (2 * h)
    if with_scale and problem.estimate_scale:
        Jp = np.vstack([Jp, np.eye(n)[-1]])
    C = Jp @ res.cov @ Jp.T
    return 0.5 * (C + C.T)
