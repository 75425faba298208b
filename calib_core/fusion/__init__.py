"""Fuse sonar clouds and camera images with a calibration (the paper's Figs. 3-5).

- :mod:`calib_core.fusion.cloud`: projection of sonar points (eq. 11), segmentation masks,
  visibility and cloud colouring (one camera or the best of several).
- :mod:`calib_core.fusion.zbuffer`: splatted z-buffers for occlusion.
- :mod:`calib_core.fusion.draw`: overlays, markers and ellipses drawn for people.

Callers import from here (``from calib_core import fusion``; ``fusion.project_cloud``).
"""

from calib_core.fusion.cloud import (CameraView, colour_cloud, colour_cloud_multi, project_cloud, sample_bilinear,
                                     segmentation_mask, visible_points)
from calib_core.fusion.draw import draw_detection, draw_ellipse, draw_marker, overlay
from calib_core.fusion.zbuffer import depth_buffer

__all__ = ["CameraView", "colour_cloud", "colour_cloud_multi", "depth_buffer", "draw_detection", "draw_ellipse",
           "draw_marker", "overlay", "project_cloud", "sample_bilinear", "segmentation_mask", "visible_points"]
