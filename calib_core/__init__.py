"""sonarcal core library: camera-to-3D-imaging-sonar calibration.

Pure functions and small dataclasses over numpy arrays. No UI, no printing.
Frames: camera frames follow OpenCV (x right, y down, z forward); the sonar
frame is whatever the sonar software wrote the cloud in. Transforms are named
``T_target_source`` and map points in ``source`` to ``target``. Units: metres,
radians, pixels.
"""

__version__ = "0.1.0"
