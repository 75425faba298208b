"""The self-contained HTML report of a session and its calibration (``sonarcal report``).

- :mod:`calib_core.report.page`: the HTML page and its sections; :func:`write_report`.
- :mod:`calib_core.report.captures`: per-capture pictures and numbers (no HTML).
- :mod:`calib_core.report.motion`: the target-motion section of imported sessions.
- :mod:`calib_core.report.render`: pictures drawn with numpy/OpenCV, as data URIs.
- :mod:`calib_core.report.svg`: small inline-SVG charts.
"""

from calib_core.report.page import ReportOptions, build_report, write_report

__all__ = ["ReportOptions", "build_report", "write_report"]
