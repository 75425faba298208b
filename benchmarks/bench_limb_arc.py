"""The lopsided limb's floor (calib_core.detect.image.limb) on a partly hidden outline: what the
edges' noise alone, and a small smooth deviation the harmonics 0-3 do not model, make of it.

Residuals drawn on an arc of the outline (the share seen: the free search accepts 0.5, the look at
the predicted place 0.35), one edge per 2 px of a 300-edge outline, white noise of ``--sigma`` px
(corr_points 1); with ``--h4`` px of a 4th harmonic at a random phase added in a second column.
Prints per share: the arc's condition number (columns 1, cos, sin and the harmonics 2-3), the
RMS floor sqrt(mean floor) px and the share of draws with a floor above 0.05 px.

    .venv/bin/python benchmarks/bench_limb_arc.py [--draws 400] [--sigma 0.2] [--h4 0.1]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from calib_core.detect.image.limb import lopsided_floor_px2  # noqa: E402

EDGES_WHOLE = 300
SHARES = (1.0, 0.8, 0.6, 0.5, 0.4, 0.35, 0.3)


def floors_px2(share: float, draws: int, sigma_px: float, h4_px: float, rng: np.random.Generator) -> np.ndarray:
    """Floors (px^2) of ``draws`` arcs of ``share`` of the outline: noise, plus ``h4_px`` of a 4th harmonic."""
    n = int(share * EDGES_WHOLE)
    th = np.linspace(0.0, 2 * np.pi * share, n, endpoint=False)
    out = []
    for _ in range(draws):
        r = rng.normal(0.0, sigma_px, n) + h4_px * np.cos(4 * th + rng.uniform(0, 2 * np.pi))
        out.append(lopsided_floor_px2(r, th, sigma_px, 1.0))
    return np.asarray(out)


def condition(share: float) -> float:
    n = int(share * EDGES_WHOLE)
    th = np.linspace(0.0, 2 * np.pi * share, n, endpoint=False)
    cols = [np.ones(n), np.cos(th), np.sin(th)] + [f(k * th) for k in (2, 3) for f in (np.cos, np.sin)]
    return float(np.linalg.cond(np.column_stack(cols)))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--draws", type=int, default=400)
    ap.add_argument("--sigma", type=float, default=0.2, help="edge noise px")
    ap.add_argument("--h4", type=float, default=0.1, help="4th harmonic px (second column)")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(0)
    print(f"edges {args.sigma} px white; {args.draws} draws per share; code: {ROOT}")
    print(f"share seen | cond | noise: RMS floor px | > 0.05 px | + {args.h4} px 4th harmonic: RMS floor px | > 0.05 px")
    for share in SHARES:
        a = floors_px2(share, args.draws, args.sigma, 0.0, rng)
        b = floors_px2(share, args.draws, args.sigma, args.h4, rng)
        print(f"{share:.2f} | {condition(share):.0f} | {np.sqrt(a.mean()):.3f} | {100 * np.mean(a > 0.05 ** 2):.1f} % | "
              f"{np.sqrt(b.mean()):.3f} | {100 * np.mean(b > 0.05 ** 2):.1f} %", flush=True)


if __name__ == "__main__":
    main()
