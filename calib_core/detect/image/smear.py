"""Reading a motion-smeared outline: the smear measured from the edges, the outline read at the
ramps' middles.

A ball that moves by a vector of length L during the exposure images as its disc convolved with
a line of length L (a stadium-like shape). Where the outline's normal makes an angle theta with
the motion, the edge is a linear ramp of width ~ L |cos theta| (plus the optics' own blur), and
the ramp's middle lies on the outline of the ball at mid-exposure; across the motion the edge
stays sharp. The still scene shows through a ramp: its sharp texture edges, not the ramp, hold
the strongest gradient peaks there, so a peak reading lands anywhere on the ramp.

Here each normal's profile is matched against a bank of ramp templates (zero-mean, unit norm,
one fixed window, so the explained energies of different widths compare): the template that
explains the most energy gives that normal's edge width. Over the outline the widths follow
w^2 = w0^2 + L^2 cos^2(theta - phi) = b0 + b1 cos 2 theta + b2 sin 2 theta (a robust linear fit),
so the motion's length L = sqrt(2 sqrt(b1^2 + b2^2)) and direction phi are measured from the
image; the smear counts as real when that amplitude stands out from its own standard error by
SMEAR_SIGMAS and its narrowest width (across the motion) is a sharp edge's. Each normal's edge is then the position of the best match of the template of the
width the fit predicts for it (a matched filter: the ramp's middle, with the texture behind it
averaged over the whole ramp rather than picked at one stud).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import correlate1d, gaussian_filter1d

from calib_core.detect.image.blur import SHARP_EDGE_WIDTH_PX

STEP_PX = 0.5
# room on each side of the widest ramp in the template window: the plateaus the levels come from
MARGIN_PX = 3.0
# the optics' (and the signal's SMOOTH_SIGMA_PX) blur of a sharp edge, as a Gaussian sigma (px)
BASE_SIGMA_PX = 1.0
# ramp widths tried, px; a smear up to half the apparent radius (beyond it the ball's two ends
# and its core are no longer one round outline)
BANK_PX = (0.0, 1.5, 3.0, 4.5, 6.0, 8.0, 10.0, 12.5, 15.0, 18.0, 22.0, 27.0, 33.0)
MAX_RADIUS_FRACTION = 0.5
# a real smear: the anisotropy's amplitude this many standard errors above zero
SMEAR_SIGMAS = 3.0
# a sharp photograph's edge (blur.SHARP_EDGE_WIDTH_PX, the FWHM of its gradient after a
# BASE_SIGMA_PX smoothing: a Gaussian blur of sigma s = sqrt((FWHM / 2.3548)^2 - BASE^2)) as the
# width of the linear ramp of the same variance (w^2 / 12 = s^2): ~4.8 px
SHARP_RAMP_PX = float(np.sqrt(12.0 * ((SHARP_EDGE_WIDTH_PX / 2.3548) ** 2 - BASE_SIGMA_PX ** 2)))


@dataclass
class Smear:
    """A smear measured around an outline."""

    length_px: float  # L (0 when the anisotropy does not stand out)
    angle_rad: float  # direction of the motion in the image (mod pi)
    real: bool  # the anisotropy stood out from its standard error by SMEAR_SIGMAS
    coef: np.ndarray  # (b0, b1, b2) of w^2 over the normals' angles


def bank(radius_px: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ramp widths (px) for an outline of this radius, their templates (n_w, n): inside
    (negative offsets) 1, outside 0, a linear ramp between, blurred by BASE_SIGMA_PX, zero-mean,
    unit norm, all over the same window; and each ramp's norm before that scaling (a unit step
    of that width explains this norm squared: the step's size is sqrt(energy) / norm)."""
    widths = np.array([w for w in BANK_PX if w <= MAX_RADIUS_FRACTION * radius_px])
    half = 0.5 * widths.max() + MARGIN_PX
    n = int(np.ceil(half / STEP_PX))
    tt = np.arange(-n, n + 1) * STEP_PX
    out, norms = [], []
    for w in widths:
        r = np.clip(0.5 - tt / w, 0.0, 1.0) if w > 0 else np.where(tt < 0, 1.0, np.where(tt > 0, 0.0, 0.5))
        r = gaussian_filter1d(r, BASE_SIGMA_PX / STEP_PX, mode="nearest")
        r -= r.mean()
        norms.append(np.linalg.norm(r))
        out.append(r / norms[-1])
    return widths, np.array(out), np.array(norms)


def energies(profiles: np.ndarray, templates: np.ndarray) -> np.ndarray:
    """(n_w, K, M) energy each template explains at each position of each profile (K, M, c),
    summed over the channels (the squared least-squares step of the template, per unit norm)."""
    out = np.zeros((len(templates),) + profiles.shape[:2])
    for i, tmpl in enumerate(templates):
        for c in range(profiles.shape[2]):
            out[i] += correlate1d(profiles[:, :, c], tmpl, axis=1, mode="nearest") ** 2
    return out


def window_px(radius_px: float) -> float:
    """Half the template window (px): profiles must reach this far beyond the band searched."""
    widths, _, _ = bank(radius_px)
    return 0.5 * float(widths.max()) + MARGIN_PX


def measure(theta: np.ndarray, widths: np.ndarray, corr_points: float) -> Smear:
    """The smear from per-normal edge widths (px) at outward normal angles ``theta`` (rad): a
    robust (Huber) fit of w^2 = b0 + b1 cos 2 theta + b2 sin 2 theta; ``corr_points``: how many
    neighbouring normals share one independent error (inflates the standard error)."""
    A = np.column_stack([np.ones_like(theta), np.cos(2 * theta), np.sin(2 * theta)])
    y = widths ** 2
    wt = np.ones_like(y)
    b, scale = np.zeros(3), 0.0
    for _ in range(5):
        b = np.linalg.lstsq(A * wt[:, None], y * wt, rcond=None)[0]
        r = y - A @ b
        scale = 1.4826 * float(np.median(np.abs(r))) + 1e-6
        wt = np.minimum(1.0, 1.345 * scale / np.maximum(np.abs(r), 1e-9))
    amp = float(np.hypot(b[1], b[2]))
    cov = scale ** 2 * np.linalg.pinv((A * wt[:, None]).T @ A) * max(corr_points, 1.0)
    # (the amplitude's standard error: the larger of the two anisotropy terms' errors)
    sd = float(np.sqrt(max(cov[1, 1], cov[2, 2])))
    # across the motion the edge is not smeared: the narrowest width squared the fit gives,
    # b0 - amp, must be a sharp edge's within its standard error (oriented texture, brick
    # courses, makes widths that vary with the angle too, but no sharp edge where they are narrowest)
    narrowest_sd = float(np.sqrt(cov[0, 0] + sd ** 2))
    # (and a smear no longer than a sharp edge's width changes no edge: none to read)
    real = (amp > SMEAR_SIGMAS * sd and b[0] - amp <= SHARP_RAMP_PX ** 2 + SMEAR_SIGMAS * narrowest_sd
            and 2.0 * amp > SHARP_RAMP_PX ** 2)
    return Smear(float(np.sqrt(2.0 * amp)) if real else 0.0, 0.5 * float(np.arctan2(b[2], b[1])), bool(real), b)


def model_widths(smear: Smear, theta: np.ndarray) -> np.ndarray:
    """Edge widths (px) the measured smear gives at outward normal angles ``theta``."""
    b = smear.coef
    return np.sqrt(np.maximum(b[0] + b[1] * np.cos(2 * theta) + b[2] * np.sin(2 * theta), 0.0))


def free_widths(E: np.ndarray, widths: np.ndarray, in_band: np.ndarray) -> np.ndarray:
    """(K,) each normal's best-matching ramp width (px) within the band searched."""
    best = np.where(in_band[None, None, :], E, -1.0).max(axis=2)  # (n_w, K)
    return widths[best.argmax(axis=0)]


def edges_at_widths(E: np.ndarray, widths: np.ndarray, w_k: np.ndarray, t: np.ndarray,
                    in_band: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t_edge (K,), explained energy (K,)): each normal's best match position within the band of
    the template of width ``w_k`` (energies interpolated between the two nearest widths of the
    bank), sub-sample by a parabola through the peak."""
    K = E.shape[1]
    j = np.clip(np.searchsorted(widths, w_k) - 1, 0, len(widths) - 2) if len(widths) > 1 else np.zeros(K, int)
    rows = np.arange(K)
    if len(widths) > 1:
        f = np.clip((w_k - widths[j]) / (widths[j + 1] - widths[j]), 0.0, 1.0)
        e = (1.0 - f)[:, None] * E[j, rows] + f[:, None] * E[j + 1, rows]
    else:
        e = E[0]
    e = np.where(in_band[None, :], e, -1.0)
    i = np.clip(e.argmax(axis=1), 1, e.shape[1] - 2)
    g0, g1, g2 = e[rows, i - 1], e[rows, i], e[rows, i + 1]
    den = g0 - 2 * g1 + g2
    off = np.where(np.abs(den) > 1e-12, 0.5 * (g0 - g2) / np.where(den == 0, 1.0, den), 0.0)
    return t[i] + np.clip(off, -0.5, 0.5) * STEP_PX, g1


def read(profiles: np.ndarray, t: np.ndarray, in_band: np.ndarray, theta: np.ndarray, radius_px: float,
         corr_points: float, min_step: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, Smear]:
    """Read an outline's edges as ramps.

    Args:
        profiles: (K, M, c) colour profiles along the K normals at offsets ``t`` (M,), step
            STEP_PX, reaching :func:`window_px` beyond the band searched.
        in_band: (M,) offsets searched; theta: (K,) outward normal angles (rad).
        corr_points: normals per independent error (see :func:`measure`).
        min_step: the least colour step (the profiles' units) of an edge: the smear is measured
            on the normals whose best ramp stands for at least this step (a hidden or faint
            stretch of the outline has widths of its own, not the smear's).

    Returns:
        t_edge (K,) px, step size (K,) in the profiles' units (the colour step each matched ramp
        stands for), the model widths (K,) px, and the measured :class:`Smear`.
    """
    widths, templates, norms = bank(radius_px)
    E = energies(profiles, templates)
    best = np.where(in_band[None, None, :], E, -1.0).max(axis=2)  # (n_w, K)
    wi = best.argmax(axis=0)
    seen = np.sqrt(np.maximum(best.max(axis=0), 0.0)) / norms[wi] >= min_step
    if seen.sum() >= 12:
        smear = measure(theta[seen], widths[wi][seen], corr_points)
    else:
        smear = Smear(0.0, 0.0, False, np.array([SHARP_RAMP_PX ** 2, 0.0, 0.0]))
    w_k = np.clip(model_widths(smear, theta), widths[0], widths[-1])
    t_edge, e = edges_at_widths(E, widths, w_k, t, in_band)
    return t_edge, np.sqrt(np.maximum(e, 0.0)) / np.interp(w_k, widths, norms), w_k, smear
