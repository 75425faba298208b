"""Marker labels stay whole inside the image, whatever the marker's position."""

from __future__ import annotations

import numpy as np
import pytest

from calib_core.fusion.draw import draw_marker


@pytest.mark.parametrize("uv", [(318.0, 120.0), (2.0, 2.0), (318.0, 238.0), (160.0, 120.0)])
def test_label_is_not_cut_at_the_image_edge(uv):
    img = np.zeros((240, 320, 3), np.uint8)
    draw_marker(img, uv, (0, 255, 0), "cross", size_px=6, label="detected")
    ref = np.zeros((240, 320, 3), np.uint8)
    draw_marker(ref, uv, (0, 255, 0), "cross", size_px=6)
    text = np.any(img != ref, axis=2)  # pixels of the label alone
    ys, xs = np.nonzero(text)
    assert len(xs) > 50
    # the whole label is inside, with a margin: nothing touches the border
    assert xs.min() >= 1 and xs.max() <= 318 and ys.min() >= 1 and ys.max() <= 238
    assert xs.max() - xs.min() > 40  # drawn whole, not squeezed against the edge
