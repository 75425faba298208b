"""A ball resting on a block whose front face, under the ball, outnumbers the ball's returns
in the detector's crop: the fit must not slide down into the block."""
import numpy as np

from calib_core.detect.sonar import detect_sphere_in_cloud


def _ray_cast(dirs, c, r, box_lo, box_hi):
    """First hit (range, m) along unit ``dirs`` from the origin on a sphere or an axis-aligned box."""
    b = dirs @ c
    disc = b * b - (c @ c - r * r)
    t_s = np.where(disc > 0, b - np.sqrt(np.clip(disc, 0, None)), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = box_lo / dirs, box_hi / dirs
    t_near = np.nanmax(np.minimum(t1, t2), axis=1)
    t_far = np.nanmin(np.maximum(t1, t2), axis=1)
    t_b = np.where((t_near <= t_far) & (t_near > 0), t_near, np.inf)
    return np.minimum(t_s, t_b)


def test_ball_resting_on_a_wide_block_is_found():
    rng = np.random.default_rng(3)
    r, c = 0.1, np.array([1.0, -0.5, 0.1])
    half = 1.2 * r  # the block is wider than the ball: its front face lies in front of it
    lo = np.array([c[0] - half, c[1] - half, -0.85])
    hi = np.array([c[0] + half, c[1] + half, c[2] - 0.98 * r])
    az, el = np.meshgrid(np.radians(np.arange(-45, 45, 0.35)), np.radians(np.arange(-30, 20, 0.35)))
    d = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], -1).reshape(-1, 3)
    t = _ray_cast(d, c, r, lo, hi)
    wall = 4.0 / np.clip(d[:, 0], 1e-3, None)  # a far wall behind everything
    t = np.minimum(t, wall) + rng.normal(0, 0.005, len(d))
    P = d * t[:, None]
    det = detect_sphere_in_cloud(P, r, beam_width_deg=0.001)
    assert det.found, det.reason
    assert np.linalg.norm(det.center_sonar_m - c) < 0.01
