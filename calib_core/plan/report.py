"""Words and table rows of a plan, built once for the CLI and the workbench."""

from __future__ import annotations

import numpy as np

from calib_core.plan.select import Plan


def _fmt_sigma(r: np.ndarray, t: np.ndarray) -> str:
    return f"{r.max():.3f} deg / {t.max():.1f} mm"


def status_line(plan: Plan) -> str:
    """'enough' or 'not yet' against the target, with the worst camera's sigma now."""
    worst = "; ".join(f"{c} {_fmt_sigma(r, t)}" for c, (r, t) in plan.current.items())
    if plan.met:
        return f"enough: every camera meets {plan.target.text()} (now worst axis {worst})"
    return f"not yet: target {plan.target.text()}; now worst axis {worst} ({plan.ratio_now:.1f}x the target)"


def criterion_text(plan: Plan) -> str:
    if plan.criterion == "d":
        return "D-optimal (largest gain in log det of each camera's 6x6 pose information)"
    return "worst axis (smallest worst 1-sigma relative to the target over all cameras)"


def suggestion_rows(plan: Plan, field=None, cameras: list[str] | None = None):
    """(columns, rows): rank, sonar-frame centre (m), range/azimuth/elevation, pixel per camera, sigma after."""
    cameras = cameras or list(plan.current)
    cols = ["#", "sonar x, y, z (m)", "range, az, el"] + [f"{c} u, v (px)" for c in cameras] + ["1-sigma after (worst axis)"]
    rows = []
    for i, s in enumerate(plan.suggestions, 1):
        X = s.X_sonar_m
        polar = ""
        if field is not None:
            az, el, r = field.angles(X[None])
            polar = f"{r[0]:.2f} m, {az[0]:+.0f} deg, {el[0]:+.0f} deg"
        px = [f"{s.uv_px[c][0]:.0f}, {s.uv_px[c][1]:.0f} (r {s.radius_px[c]:.0f})" if c in s.uv_px else "not in view"
              for c in cameras]
        after = "; ".join(f"{c} {_fmt_sigma(r, t)}" for c, (r, t) in s.sigma_after.items())
        mark = " (enough)" if s.ratio_after <= 1.0 else ""
        rows.append([str(i), f"{X[0]:+.2f}, {X[1]:+.2f}, {X[2]:+.2f}", polar, *px, after + mark])
    return cols, rows


def compact_rows(plan: Plan):
    """(columns, rows) for a narrow panel: rank, sonar-frame centre, range, worst axis after over all cameras."""
    cols = ["#", "sonar x, y, z (m)", "range (m)", "then (worst axis)"]
    rows = []
    for i, s in enumerate(plan.suggestions, 1):
        X = s.X_sonar_m
        r = max(v[0].max() for v in s.sigma_after.values())
        t = max(v[1].max() for v in s.sigma_after.values())
        rows.append([str(i), f"{X[0]:+.2f}, {X[1]:+.2f}, {X[2]:+.2f}", f"{np.linalg.norm(X):.2f}",
                     f"{r:.3f} deg / {t:.1f} mm" + (" (enough)" if s.ratio_after <= 1.0 else "")])
    return cols, rows


def plan_lines(sp) -> list[str]:
    """Plain-text summary lines of a SessionPlan (status, criterion, limits, field, skipped cameras)."""
    f = sp.field
    lines = [status_line(sp.plan), f"criterion: {criterion_text(sp.plan)}",
             f"limits: {sp.limits.text()}",
             f"sonar field: azimuth {f.azimuth_deg[0]:.0f}..{f.azimuth_deg[1]:.0f} deg, elevation "
             f"{f.elevation_deg[0]:.0f}..{f.elevation_deg[1]:.0f} deg, range {f.range_m[0]:.1f}-{f.range_m[1]:.1f} m "
             f"(from {f.source})",
             f"{sp.plan.n_candidates} candidate positions seen by the sonar and a camera; 'after' sigmas are cumulative "
             f"(suggestion k assumes 1..k-1 were taken too)"]
    lines += [f"{c}: not planned ({why})" for c, why in sp.skipped.items()]
    lines += sp.plan.notes
    return lines
