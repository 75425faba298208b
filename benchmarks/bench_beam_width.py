"""Effective beam width: the coarse-to-fine search against the full grid, on generated sessions.

    .venv/bin/python benchmarks/bench_beam_width.py SESSION [SESSION ...]

For each session (e.g. the canal / seabed / LiDAR / RGB-D presets of calib_core.synth), the
captures' crops (calib_core.detect.sonar.beam.beam_crop) are computed once, then the width is
estimated by the default coarse-to-fine search with warm-started fits and by the full grid of
factors with cold fits (the estimator before issue 12's second round). Prints both widths,
their difference and the scan times (crops excluded), with the load average.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from calib_core import pipeline  # noqa: E402
from calib_core.detect.sonar.beam import estimate_from_crops  # noqa: E402
from calib_core.session import load_session  # noqa: E402


def main(argv=None):
    roots = [Path(p) for p in (sys.argv[1:] if argv is None else argv)]
    print(f"load average before: {os.getloadavg()}")
    print(f"{'session':>16} {'n':>3} | {'grid deg':>8} {'fits':>4} {'s':>5} | {'c2f deg':>8} {'fits':>4} {'s':>5} | "
          f"{'diff % of nominal':>17}")
    for root in roots:
        s = load_session(root)
        data = pipeline.as_data(s)
        ids = pipeline.beam_capture_ids([c.id for c in s.captures])
        crops = [pipeline.beam_crop_of(data, c, {}) for c in ids]
        nominal = s.beam_width_deg or 1.0
        out = []
        for search in ("grid", "coarse-to-fine"):
            t = time.perf_counter()
            e = estimate_from_crops(crops, s.sphere_radius_m, nominal, search=search)
            out.append((e.beam_width_deg, len(e.factors) * e.n_captures, time.perf_counter() - t, e.n_captures))
        (g, gf, gt, n), (c, cf, ct, _) = out
        print(f"{root.name:>16} {n:>3} | {g:>8.4f} {gf:>4} {gt:>5.2f} | {c:>8.4f} {cf:>4} {ct:>5.2f} | "
              f"{100 * (c - g) / nominal:>+17.2f}")
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
