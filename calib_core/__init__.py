"""sonarcal core library: camera-to-3D-imaging-sonar calibration.

Pure functions and small dataclasses over numpy arrays. No UI, no printing.
Frames: camera frames follow OpenCV (x right, y down, z forward); the sonar
frame is whatever the sonar software wrote the cloud in. Transforms are named
``T_target_source`` and map points in ``source`` to ``target``. Units: metres,
radians, pixels.
"""

import os as _os

__version__ = "0.1.0"

# The largest camera frame decoded (7680 x 5120; RGB at this size is 120 MB). OpenCV reads its
# own decoder cap from the environment once, when cv2 is imported: set it before any import of
# cv2 as a second line of defence behind the header checks of calib_core.io.images.
MAX_IMAGE_PIXELS = 40_000_000
_os.environ.setdefault("OPENCV_IO_MAX_IMAGE_PIXELS", str(MAX_IMAGE_PIXELS))
