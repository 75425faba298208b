"""A ball resting on a chair, and round-looking clutter that is no sphere (issue 11, third round).

``lidar-chair`` seed 41: a grey ball before a grey-green wall with the chair's dark backrest
right behind it and the seat's edge along its bottom. The edges of the backrest and the seat
run a few px outside the ball's outline and pulled the cone fit off (found 3 px+ off or not at
all in 4 of 8 images); the chair's leg joints made "round outlines" of their own.
"""

import cv2
import numpy as np
import pytest

from calib_core.camera import CameraModel
from calib_core.detect.image.detect import detect_sphere_in_image
from calib_core.io.images import load_image
from calib_core.pipeline import SessionData
from calib_core.session import load_session
from calib_core.synth.generate import generate_session
from calib_core.synth.ground_truth import load_ground_truth


@pytest.fixture(scope="module")
def chair_session(tmp_path_factory):
    root = generate_session(tmp_path_factory.mktemp("chair") / "lidar-chair", "lidar-chair", 41, scale=0.5)
    return SessionData(load_session(root)), load_ground_truth(root)


@pytest.mark.parametrize("cid", ["p01", "p02", "p05", "p06", "p08"])
def test_ball_on_a_chair_found_at_the_true_centre(chair_session, cid):
    data, gt = chair_session
    model = data.camera("cam1")
    img = load_image(data.session.capture(cid).image_paths["cam1"], (model.width_px, model.height_px))
    det = detect_sphere_in_image(img, model, data.session.sphere_radius_m)
    assert det.found, det.reason
    true_uv = np.asarray(gt["captures"][cid]["images"]["cam1"]["center_uv_px"])
    assert np.hypot(*(det.center_uv_px - true_uv)) < 1.5
    assert det.score >= 0.5


def _cam(w=640, h=480):
    return CameraModel(w, h, np.array([[520.0, 0, w / 2], [0, 520.0, h / 2], [0, 0, 1]]))


def test_small_rounded_icon_on_a_bright_screen_is_not_a_sphere():
    # a dark rounded rectangle (~8 px) on a white screen, as on a monitor in a lab: strong edges,
    # roughly round, but far too rough for a circle that small
    rng = np.random.default_rng(3)
    img = np.full((480, 640, 3), 90, np.uint8)
    cv2.rectangle(img, (250, 150), (450, 300), (245, 245, 245), -1)
    cv2.rectangle(img, (342, 218), (358, 230), (20, 20, 20), -1)
    cv2.circle(img, (345, 221), 3, (20, 20, 20), -1)
    img = np.clip(cv2.GaussianBlur(img, (0, 0), 0.7) + rng.normal(0, 2.0, img.shape), 0, 255).astype(np.uint8)
    det = detect_sphere_in_image(img, _cam(), 0.203)
    assert not det.found or det.score < 0.5


def test_disc_against_a_touching_dark_slab_is_found():
    # a grey disc whose left half lies in front of a darker slab and whose bottom rests on a bar:
    # the slab's and the bar's edges run 2-4 px outside the outline over a third of it
    rng = np.random.default_rng(5)
    cam = _cam()
    img = np.full((480, 640, 3), (105, 128, 118), np.float32)
    cv2.rectangle(img, (255, 150), (330, 330), (70, 80, 72), -1)  # backrest, 3 px left of the disc
    cv2.rectangle(img, (255, 318), (380, 326), (60, 66, 60), -1)  # seat, touching the bottom
    mask = np.zeros((480 * 8, 640 * 8), np.uint8)
    cv2.circle(mask, (int(318.5 * 8), int(278.5 * 8)), 40 * 8, 255, -1)
    cover = cv2.resize(mask.astype(np.float32) / 255, (640, 480), interpolation=cv2.INTER_AREA)[..., None]
    img = img * (1 - cover) + np.array([112, 122, 120], np.float32) * cover
    img = np.clip(cv2.GaussianBlur(img, (0, 0), 0.8) + rng.normal(0, 2.0, img.shape), 0, 255).astype(np.uint8)
    # a circle of 40 px at (318.5, 278.5) is a sphere's outline only near the image centre; the
    # test asks for the outline's place, not the exact projection: within 1.5 px of its centre
    det = detect_sphere_in_image(img, cam, 0.3)
    assert det.found, det.reason
    assert np.hypot(det.center_uv_px[0] - 318.5, det.center_uv_px[1] - 278.5) < 1.5
