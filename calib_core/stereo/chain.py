"""Stereo transforms chained through the cameras that tie them, with their covariances carried
to first order.

A session may tie each camera only to one reference (``T_cam2_cam1``, ``T_cam3_cam1``): then
``T_cam3_cam2 = T_cam3_cam1 @ inv(T_cam2_cam1)``. Covariances are 6x6 over the solver's
perturbation (:meth:`calib_core.solve.refine.RigProblem.apply`): rotation vector (rad),
left-multiplied (``R' = exp(w) R``), and an additive translation (m), ``t' = t + dt``. To first
order, for ``T_ba = T_bc @ T_ca``::

    w_ba  = w_bc + R_bc w_ca
    dt_ba = dt_bc - [R_bc t_ca]x w_bc + R_bc dt_ca

and for ``inv(T)`` = (R^T, -R^T t)::

    w_inv  = -R^T w
    dt_inv = -R^T dt - R^T [t]x w
"""

from __future__ import annotations

from collections import deque

import numpy as np

from calib_core.geometry import invert_T


def _skew(v: np.ndarray) -> np.ndarray:
    x, y, z = np.asarray(v, float)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def invert_with_cov(T: np.ndarray, cov6: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(inv(T), its 6x6 covariance) to first order."""
    R, t = T[:3, :3], T[:3, 3]
    J = np.zeros((6, 6))
    J[:3, :3] = -R.T
    J[3:, :3] = -R.T @ _skew(t)
    J[3:, 3:] = -R.T
    return invert_T(T), J @ cov6 @ J.T


def compose_with_cov(T_bc: np.ndarray, cov_bc: np.ndarray, T_ca: np.ndarray, cov_ca: np.ndarray):
    """(T_bc @ T_ca, its 6x6 covariance) to first order, the two transforms independent."""
    R_bc = T_bc[:3, :3]
    J1 = np.eye(6)
    J1[3:, :3] = -_skew(R_bc @ T_ca[:3, 3])
    J2 = np.zeros((6, 6))
    J2[:3, :3] = R_bc
    J2[3:, 3:] = R_bc
    return T_bc @ T_ca, J1 @ cov_bc @ J1.T + J2 @ cov_ca @ J2.T


def _splits(key: str, cameras) -> list[tuple[str, str]]:
    """The (target, source) readings of a stereo key ``T_<target>_<source>``. Camera names may hold
    '_' (the bag importer's ``stereo_left``), so every '_' is a possible border; with the session's
    ``cameras`` only the readings naming two of them are kept."""
    if not key.startswith("T_"):
        return []
    rest = key[2:]
    out = [(rest[:i], rest[i + 1:]) for i, ch in enumerate(rest) if ch == "_" and 0 < i < len(rest) - 1]
    return out if cameras is None else [(b, a) for b, a in out if b in cameras and a in cameras]


def _edges(stereo: dict, cameras=None) -> dict:
    """{camera: [neighbour, ...]} of the stereo keys ``T_<target>_<source>`` (both directions)."""
    out: dict = {}
    for key in stereo:
        for b, a in _splits(key, None if cameras is None else set(cameras)):
            out.setdefault(a, []).append(b)
            out.setdefault(b, []).append(a)
    return out


def stereo_path(stereo: dict, a: str, b: str, cameras=None) -> list[str] | None:
    """The shortest chain of cameras [a, ..., b] tied pairwise by stated stereo transforms
    (breadth first; ties broken by the order of the keys), or None. ``cameras``: the session's
    camera names (they disambiguate keys whose names hold '_'); None reads every split."""
    edges, prev, todo = _edges(stereo, cameras), {a: None}, deque([a])
    while todo:
        c = todo.popleft()
        if c == b:
            path = [b]
            while prev[path[-1]] is not None:
                path.append(prev[path[-1]])
            return path[::-1]
        for n in edges.get(c, []):
            if n not in prev:
                prev[n] = c
                todo.append(n)
    return None


def _link(stereo: dict, cov_of, a: str, b: str) -> tuple[np.ndarray, np.ndarray]:
    """(T_b_a, cov) of one stated transform, inverted when the session states ``T_a_b``."""
    if f"T_{b}_{a}" in stereo:
        return np.asarray(stereo[f"T_{b}_{a}"], float), np.asarray(cov_of(f"T_{b}_{a}"), float)
    return invert_with_cov(np.asarray(stereo[f"T_{a}_{b}"], float), np.asarray(cov_of(f"T_{a}_{b}"), float))


def chained_stereo(stereo: dict, cov_of, a: str, b: str, cameras=None):
    """(T_b_a, 6x6 covariance, [a, ..., b]) along the shortest chain of stated stereo transforms,
    or None when no chain ties ``a`` to ``b``. ``cov_of(key)``: the stated covariance of
    ``stereo[key]``; ``cameras``: as in :func:`stereo_path`."""
    path = None if a == b else stereo_path(stereo, a, b, cameras)
    if path is None:
        return None
    T, cov = np.eye(4), np.zeros((6, 6))
    for src, dst in zip(path[:-1], path[1:]):
        T_step, cov_step = _link(stereo, cov_of, src, dst)
        T, cov = compose_with_cov(T_step, cov_step, T, cov)
    return T, cov, path
