"""``sonarcal info SESSION``: summary of a session and every validation problem."""


from __future__ import annotations

from rich.markup import escape

from calib_core.session import validate_session
from sonarcal_cli.ui import console, err_console, table


def add_parser(sub) -> None:
    p = sub.add_parser("info", help="summarise a session and list every problem in it")
    p.add_argument("session", help="session folder (holds session.yaml)")
    p.set_defaults(run=run)


def run(args) -> int:
    check = validate_session(args.session)
    s = check.session
    if s is not None:
        console.print(f"[bold]{escape(s.name)}[/bold]  ({escape(str(s.root))})")
        console.print(f"sphere diameter {s.sphere_diameter_m * 1000:.1f} mm; sonar {s.sonar_model or '-'}; "
                      f"sound speed {s.sound_speed_m_s or '-'} m/s; beam width {s.beam_width_deg:g} deg")
        cam_rows = []
        for name, spec in s.cameras.items():
            m = check.cameras.get(name)
            cam_rows.append([name, spec.intrinsics_path.relative_to(s.root),
                             f"{m.width_px}x{m.height_px}" if m else "?",
                             f"{m.fx:.1f} / {m.fy:.1f}" if m else "?",
                             m.distortion_model if m else "?",
                             spec.background_path.relative_to(s.root) if spec.background_path else "-"])
        console.print(table("Cameras", ["camera", "intrinsics", "size", "fx / fy px", "lens model", "background"], cam_rows))
        cap_rows = [[c.id, c.cloud_path.relative_to(s.root), _points_cell(check, c.id),
                     ", ".join(sorted(c.image_paths)) or "-"] for c in s.captures]
        console.print(table(f"Captures ({len(s.captures)})", ["capture", "cloud", "points", "images"], cap_rows))
        if s.measured_m:
            console.print("measured baselines: " + ", ".join(f"{k} {v:.4f} m" for k, v in s.measured_m.items()))
    if check.problems:
        err_console.print(f"[bold red]{len(check.problems)} problem(s):[/bold red]")
        for e in check.problems:
            err_console.print(f"  error: {e}", markup=False, soft_wrap=True)  # one line each, however long
        return 2
    console.print("[green]no problems found[/green]")
    return 0


def _points_cell(check, cid: str) -> str:
    """Point count, and how many rows held no return (NaN/inf or (0, 0, 0), left out)."""
    n = check.cloud_points.get(cid)
    if n is None:
        return "?"
    k = check.cloud_no_return.get(cid, 0)
    return f"{n} (+{k} without a return, left out)" if k else str(n)
