"""See-through balls (open lattice, cage, net, wiffle): the image closed at the mesh cell's scale
(calib_core.detect.image.closing) and the cue that looks there when nothing else gave a clear
outline (calib_core.detect.image.detect._closed_cue)."""

import cv2
import numpy as np

from calib_core.detect.image import closing
from calib_core.detect.image import detect as im


def _lattice(bright: bool, R=40.0, centre=(80.3, 70.6), n=12):
    """A flat drawing of a lattice ball: its limb circle drawn as dashes (gaps between strut ends)
    and a square lattice of thin struts inside it, on a plain background."""
    img = np.full((140, 160, 3), 60 if bright else 200, np.uint8)
    col = (230, 200, 40) if bright else (20, 20, 20)
    c = tuple(int(round(4 * x)) for x in centre)
    for k in range(n):  # dashes along the limb: 2/3 of each 30 deg seen
        a0 = 360.0 * k / n
        cv2.ellipse(img, c, (int(4 * R) - 4, int(4 * R) - 4), 0, a0, a0 + 20, col, 3, cv2.LINE_AA, shift=2)
    for off in np.arange(-R + 4, R - 3, 7.0):  # a square lattice of cells 7 px wide inside it
        h = np.sqrt(max((R - 2) ** 2 - off ** 2, 0.0))
        for p, q in (((centre[0] + off, centre[1] - h), (centre[0] + off, centre[1] + h)),
                     ((centre[0] - h, centre[1] + off), (centre[0] + h, centre[1] + off))):
            cv2.line(img, tuple(int(round(4 * x)) for x in p), tuple(int(round(4 * x)) for x in q), col, 1,
                     cv2.LINE_AA, shift=2)
    return img


def _solid_radius(img: np.ndarray, centre, bright: bool) -> tuple[float, float]:
    """(share of the disc within 0.8 of the radius that is strut-coloured, outermost radius of it)."""
    g = img[..., 1].astype(float) if bright else 255.0 - img[..., 1].astype(float)
    yy, xx = np.mgrid[:img.shape[0], :img.shape[1]]
    r = np.hypot(xx + 0.5 - centre[0], yy + 0.5 - centre[1])
    on = g > 128
    return float(on[r < 0.8 * 40].mean()), float(r[on].max())


def test_closing_fills_a_lattice_into_a_disc_and_keeps_its_limb():
    """Bright struts closed, dark struts opened, with the disc of closing.kernel_px: the cells
    fill (the ball becomes a solid disc) and the outline stays at the limb (within the struts'
    width), while the raw drawing is mostly background inside."""
    for bright in (True, False):
        img = _lattice(bright)
        raw_fill, raw_r = _solid_radius(img, (80.3, 70.6), bright)
        out = closing.closed(img, closing.kernel_px(40.0), "bright" if bright else "dark")
        fill, r = _solid_radius(out, (80.3, 70.6), bright)
        assert raw_fill < 0.6 and fill > 0.95
        assert abs(r - raw_r) < 1.5


def test_closed_around_changes_only_the_candidates_region():
    img = np.random.default_rng(0).integers(0, 255, (200, 300, 3), dtype=np.uint8)
    c = im.Candidate(np.array([60.0, 60.0]), 10.0, (10.0, 10.0), 0.0, False, 50.0, "closed-bright")
    out = closing.view_of(img, c)
    assert out.shape == img.shape and not np.array_equal(out, img)
    assert np.array_equal(out[:, 120:], img[:, 120:]) and np.array_equal(out[120:], img[120:])


def test_a_wiffle_ball_whose_holes_notch_its_outline_is_found():
    """Held-out mesh case s1008 (wiffle ball r 48 px before brick, 960x540): every reading of the
    raw image read the holes' edges (edge RMS 1.6-2.5 px, 'no round outline'); on the opened
    image the ball is a disc and its centre is found within a pixel."""
    from calib_core.synth.image_cases import render_case
    case = render_case("mesh", 1008, 0.5)
    det = im.detect_sphere_in_image(case.image, case.cam, case.radius_m)
    assert det.found, det.reason
    assert np.hypot(*(det.center_uv_px - case.true_uv_px)) < 1.0


def _fit_at(centre, r, score, width=3.0):
    a = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    sil = np.asarray(centre, float) + r * np.stack([np.cos(a), np.sin(a)], axis=1)
    return im.CandidateFit(True, "", None, np.asarray(centre, float), 0.01 * np.eye(2), sil, 0.9, score, 40.0,
                           1.0, {"edge_width_px": width}, True)


class _ClosedLook:
    """Just what _closed_cue uses: two see-through candidates, the ball's clear, a small blob's
    accepted by the fit but not by the cue's gate (radius under SMALL_RADIUS_PX)."""

    def __init__(self):
        self.fits = {60.0: _fit_at((60, 60), 30.0, 0.9), 200.0: _fit_at((200, 60), 13.0, 0.8)}

    def closed_candidates(self):
        return [im.Candidate(np.array([x, 60.0]), r, (r, r), 0.0, False, 50.0, "closed-bright")
                for x, r in ((60.0, 30.0), (200.0, 13.0))]

    def refine_closed(self, c):
        return self.fits[float(c.centre_px[0])]


def test_only_the_see_through_cues_clear_outlines_count():
    """A closed-view guess the cue's gate refuses is not kept beside the clear one: it would be an
    accepted second outline ("two round objects") that the gate was made to keep out."""
    look = _ClosedLook()
    assert im._closed_clear(look.fits[60.0]) and not im._closed_clear(look.fits[200.0])
    cands, fits = im._closed_cue(look, [], [])
    assert len(cands) == 2  # both tried
    assert [f for _, f in fits] == [look.fits[60.0]]
