"""Capture planning: where to put the sphere next, and when to stop.

Uses the solver's own covariance model (see :mod:`calib_core.plan.information`); each camera's
pose is planned as the solver solves it independently. Public API:
- :func:`calib_core.plan.session_plan.plan_session` (session, detections) -> :class:`Plan`;
  :func:`calib_core.plan.report.plan_lines` the text both shells print.
- :func:`calib_core.plan.candidates.candidates` positions the sonar and a camera can see;
  :class:`Limits`; :class:`calib_core.plan.field.SonarField`.
- :func:`calib_core.plan.select.plan_next` greedy worst-axis (default) or D-optimal suggestions.
- :class:`calib_core.plan.target.Target`, :func:`parse_target`.
- :mod:`calib_core.plan.coverage` coverage pictures.
"""

from calib_core.plan.candidates import Candidates, Limits, candidates, visibility
from calib_core.plan.field import SonarField, field_from_points
from calib_core.plan.noise import NoiseModel, default_noise, fit_noise
from calib_core.plan.select import CRITERIA, DEFAULT_CRITERION, CameraState, Plan, Suggestion, plan_next
from calib_core.plan.target import Target, parse_target

__all__ = ["CRITERIA", "DEFAULT_CRITERION", "CameraState", "Candidates", "Limits", "NoiseModel", "Plan", "SonarField", "Suggestion",
           "Target", "candidates", "default_noise", "field_from_points", "fit_noise", "parse_target", "plan_next",
           "visibility"]
