"""The fourth (pattern) cue is a guess that counts only when it gives a clear outline: when it
is discarded it must leave the detection's shared random stream as it found it, so that what
draws after it (the host search around a clipped highlight) is what it would be without the
cue (calib_core.detect.image.detect._more_cues)."""

import numpy as np

from calib_core.camera import CameraModel
from calib_core.detect.image import detect as im
from calib_core.detect.image.fit import CandidateFit
from calib_core.detect.image.region import Candidate


class _Look:
    """Just what _more_cues uses; every refinement draws from the stream and finds nothing."""

    def __init__(self, fx=2000.0):
        self.rng, self.r_bounds, self.max_candidates = np.random.default_rng(0), (5.0, 200.0), 10
        # a narrow lens (the stereographic cue does not look) unless ``fx`` makes it wide
        self.cam = CameraModel(640, 480, np.array([[fx, 0, 320.0], [0, fx, 240.0], [0, 0, 1]]))
        self.s = 1
        yy, xx = np.mgrid[0:480, 0:640]
        ring = (np.abs(np.hypot(xx - 560, yy - 70) - 40) < 3)  # a round line near a corner
        self.small = np.where(ring[..., None], 230, 40).astype(np.uint8).repeat(3, axis=2)

    def contrast_candidates(self):
        return []

    def disc_candidates(self):
        return []

    def closed_candidates(self):  # (the see-through cue after it: nothing here)
        return []

    def refine(self, c):
        self.rng.random(5)
        return CandidateFit(False, "no round outline")


def test_a_discarded_pattern_guess_leaves_the_random_stream_untouched():
    ang = np.linspace(0, 2 * np.pi, 6, endpoint=False)
    blobs = [Candidate(np.array([200 + 14 * np.cos(a), 150 + 14 * np.sin(a)]), 6.0, (6.0, 6.0), 0.0, False,
                       100.0, "votes") for a in ang]
    assert im.enclosing_candidates(blobs, (5.0, 200.0))  # the cue proposes a circle here
    look = _Look()
    cands, fits = im._more_cues(look, blobs, [])
    assert cands == blobs and fits == []  # discarded
    assert look.rng.random() == np.random.default_rng(0).random()


def test_a_discarded_stereographic_guess_leaves_the_random_stream_untouched():
    # a wide lens (fx 300 px for 640 px: the corners stretch a sphere 1.5x): the sixth cue votes in
    # the stereographic view and refines what it finds there; nothing clear, so the stream is restored
    look = _Look(fx=300.0)
    assert im.view_elongation(look.cam) >= im.STEREO_MIN_ELONGATION
    before = look.rng.bit_generator.state
    refined = []
    plain = look.refine
    look.refine = lambda c: refined.append(c) or plain(c)
    cands, fits = im._stereo_cue(look, [], [])
    assert refined and all(c.source == "votes-stereo" for c in refined)  # it looked, and drew
    assert cands == [] and fits == []
    assert look.rng.bit_generator.state == before
