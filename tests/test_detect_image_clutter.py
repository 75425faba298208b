"""Image detector on textured clutter, close balls, holders and turbid water (issue 11).

Cases come from :mod:`calib_core.synth.image_cases` at reduced scale (fast); seeds differ from
the benchmark's held-out seeds (1000+).
"""

import numpy as np
import pytest

from calib_core.detect.image.detect import detect_sphere_in_image, two_objects_reason
from calib_core.synth.image_cases import render_case
from calib_core.synth.textures import texture_factor

SCALE = 0.3


@pytest.mark.parametrize("kind,seed", [("clutter", 0), ("clutter", 2), ("clutter", 3), ("big", 1), ("turbid", 1)])
def test_found_at_the_true_centre(kind, seed):
    case = render_case(kind, seed, SCALE)
    for bg in ((case.background, None) if case.background is not None else (None,)):
        det = detect_sphere_in_image(case.image, case.cam, case.radius_m, background=bg)
        assert det.found, det.reason
        assert np.hypot(*(det.center_uv_px - case.true_uv_px)) < 0.5
        assert det.extras["outline_coverage"] >= 0.5


def test_stick_hides_part_of_the_outline_yet_found():
    case = render_case("clutter", 2, SCALE)  # a stick crosses the silhouette (label says so)
    assert case.label.endswith("stick")
    det = detect_sphere_in_image(case.image, case.cam, case.radius_m)
    assert det.found and np.hypot(*(det.center_uv_px - case.true_uv_px)) < 0.5


def test_ball_cut_by_the_border_is_reported_as_cut():
    case = render_case("big", 1, SCALE)
    shift = int(case.true_uv_px[0] - 0.3 * case.radius_px)  # move the ball ~40 % out on the left
    img = np.ascontiguousarray(np.roll(case.image, -shift, axis=1))
    img[:, -shift:] = img[:, -2 * shift:-shift][:, ::-1]  # no wrap-around copy of the ball
    det = detect_sphere_in_image(img, case.cam, case.radius_m)
    assert not det.found and det.reason == "sphere cut by the image border"


def test_no_ball_says_so():
    case = render_case("clutter", 0, SCALE)
    u, v = case.true_uv_px
    r = int(1.6 * case.radius_px) + 4
    img = case.image.copy()
    y0, x0 = max(0, int(v) - r), max(0, int(u) - r)
    img[y0:int(v) + r, x0:int(u) + r] = np.median(case.image.reshape(-1, 3), axis=0)  # paint it out
    det = detect_sphere_in_image(img, case.cam, case.radius_m)
    if det.found:  # a flat square is not round: nothing else in this scene may pass
        pytest.fail(f"false detection at {det.center_uv_px}")
    assert det.reason


def test_reason_wording():
    assert two_objects_reason([(10.2, 20.7), (300, 40)]) == "two round objects: (10, 21) and (300, 40)"


def test_textures_are_bounded_and_vary():
    rng = np.random.default_rng(0)
    p = rng.uniform(-3, 3, (2000, 3))
    n = np.tile([0.0, 0.0, 1.0], (2000, 1))
    for kind in ("brick", "tiles", "noise", "foam"):
        f = texture_factor(kind, p, n, 0.2, 0.6, 3)
        assert np.all(f > 0) and np.all(f < 2.5) and f.std() > 0.02
    with pytest.raises(ValueError):
        texture_factor("marble", p, n, 0.2, 0.6, 3)


def test_clipped_spot_and_its_hosts():
    from calib_core.detect.image.highlight import host_candidates, is_clipped_spot

    img = np.full((100, 120, 3), 120, np.uint8)
    yy, xx = np.mgrid[0:100, 0:120]
    img[(xx - 60) ** 2 + (yy - 50) ** 2 <= 36] = 255
    assert is_clipped_spot(img, (60, 50), 6.0) and not is_clipped_spot(img, (30, 50), 6.0)
    hosts = host_candidates((60, 50), 6.0, img.shape)
    assert all(h.radius_px > 12 for h in hosts) and any(np.allclose(h.centre_px, (60, 50)) for h in hosts)
