"""Camera-to-sonar solver: robust start, maximum-likelihood refinement, uncertainty, rig consistency.

Public API (frames and units in each docstring):
- :func:`calib_core.solve.calibrate.calibrate_session` (session, detections, options, progress) -> the
  calibration.json content; :class:`calib_core.solve.calibrate.CalibrateOptions`.
- :func:`calib_core.solve.model.camera_data` builds a camera's correspondences from plain arrays;
  :func:`calib_core.solve.single.solve_camera` calibrates one camera (RANSAC PnP start, ML refinement,
  optional range scale, covariance, per-capture and leave-one-out residuals, outlier flags, layout
  warnings) -> :class:`calib_core.solve.single.CameraSolution`.
- :func:`calib_core.solve.rig.solve_rig` joint solve of cameras tied by stereo transforms (range scale
  observable there); :func:`calib_core.solve.rig.table_i` the paper's Table I.
- :mod:`calib_core.solve.checkerboard`: intrinsics and stereo from checkerboard images.
- :mod:`calib_core.solve.summary`: report rows (strings) from a calibration dict.
- :mod:`calib_core.solve.simulate`: synthetic correspondences for tests and benchmarks.
"""
