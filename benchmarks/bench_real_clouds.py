"""Range-side sphere detection on a real session's clouds (default: kinectnet-dev, RGB-D).

As the pipeline does it: the effective beam width is estimated once over the session
(calib_core.detect.sonar.beam, starting from the manifest's width or 1 deg), then every cloud
is searched with it. Prints one row per cloud (found, range, diameter seen, warning or
reason) and a summary: recall, and the reasons for the misses. No ground truth exists for
these clouds; "diameter seen" against the stated one and the smoothness of the ball's path
(consecutive frames, 0.1 s apart) are the checks, and the path step is printed.

    .venv/bin/python benchmarks/bench_real_clouds.py [SESSION_DIR]

Skips (exit 0) when the session is not present (CI has no /work/shared).
"""

from __future__ import annotations

import os
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from calib_core.detect.sonar.detect import detect_sphere_in_cloud  # noqa: E402
from calib_core.detect.sonar.beam import estimate_beam_width_deg  # noqa: E402
from calib_core.io.clouds import load_cloud  # noqa: E402
from calib_core.session import load_session  # noqa: E402

DEFAULT = Path("/work/shared/data/kinectnet-dev")


def _short(text: str, n: int = 90) -> str:
    return text if len(text) <= n else text[: n - 1] + "…"


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    root = Path(argv[0]) if argv else DEFAULT
    if not (root / "session.yaml").is_file():
        print(f"skipped: no session at {root}")
        return 0
    s = load_session(root)
    r = s.sphere_radius_m
    clouds = {c.id: load_cloud(c.cloud_path).points_m for c in s.captures}
    t0 = time.perf_counter()
    est = estimate_beam_width_deg(list(clouds.values()), r, s.beam_width_deg or 1.0)
    t_est = time.perf_counter() - t0
    print(f"{root.name}: {len(clouds)} clouds, sphere {2 * r:.3f} m; effective beam width "
          f"{est.beam_width_deg:.3f} deg from {est.n_captures} spheres ({t_est:.1f} s)"
          f"{'; ' + est.reason if est.reason else ''}")
    print(f"{'cloud':6} {'points':>7} {'found':>5} {'range m':>7} {'diam m':>6} {'step mm':>7} {'ms':>5}  note")
    rows, prev, times = [], None, []
    for cid, P in clouds.items():
        t1 = time.perf_counter()
        det = detect_sphere_in_cloud(P, r, est.beam_width_deg)
        times.append(time.perf_counter() - t1)
        step = (np.linalg.norm(det.center_sonar_m - prev) * 1000
                if det.found and prev is not None else float("nan"))
        prev = det.center_sonar_m if det.found else None
        note = det.extras.get("warning", "") if det.found else det.reason
        rng_m = det.extras.get("range_m", float("nan")) if det.found else float("nan")
        diam = det.diameter_m if det.found and det.diameter_m else float("nan")
        print(f"{cid:6} {len(P):7d} {str(det.found):>5} {rng_m:7.3f} {diam:6.3f} {step:7.0f} "
              f"{1000 * times[-1]:5.0f}  {_short(note)}")
        rows.append((cid, det))
    found = [d for _, d in rows if d.found]
    warned = [d for d in found if "sphere seen" in d.extras.get("warning", "")]
    print(f"\nrecall: {len(found)}/{len(rows)} clouds with a sphere found "
          f"({len(warned)} of them with a size warning); median {1000 * np.median(times):.0f} ms "
          f"per cloud (load average {os.getloadavg()[0]:.2f})")
    diams = np.array([d.diameter_m for d in found if d.diameter_m])
    if len(diams):
        print(f"diameter seen: median {np.median(diams):.3f} m, 10-90 % {np.percentile(diams, 10):.3f}"
              f"-{np.percentile(diams, 90):.3f} m (stated {2 * r:.3f} m)")
    misses = Counter(_reason_kind(d.reason) for _, d in rows if not d.found)
    for kind, n in misses.most_common():
        print(f"  missed {n}: {kind}")
    return 0


def _reason_kind(reason: str) -> str:
    """The reason without its numbers, to group misses."""
    core = reason.split(": ", 1)[-1] if "best candidate" in reason else reason
    return core.split(" (")[0].rstrip(")")


if __name__ == "__main__":
    raise SystemExit(main())
