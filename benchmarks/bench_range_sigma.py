"""Is the image detector's apparent-size range sigma honest? Cached synthetic sessions against
the exact truth, split by class, before and after the per-camera outline bias the solver
estimates with the scale (calib_core.solve.outline).

    .venv/bin/python benchmarks/bench_range_sigma.py [--roots DIR ...] [--recompute]

Reads every ``<root>/*/`` session with ``ground_truth.yaml`` and cached detections
(``dets.pkl`` or ``solver3_dets.pkl``, pickled ``detect_session`` output; benchmarks/bench_stated_cov.py
writes them). Skips when none is there. A detection counts when its centre is within 3 px of the
truth (a right detection). Its range error is taken against the range the true cone gives with
the stated diameter (``distance * stated / true diameter``), so a preset's wrong diameter is not
counted as detector error.

Columns: z2 = mean squared (range error / stated range sigma) per detection (1 = honest);
z2|b = the same after removing each (session, camera)'s outline bias ``b`` (px, weighted least
squares on the regressor d^2 / (R f), the first-order effect of an outline moved b px; the
mean is scaled by n / (n - 1) per camera for the dof used); z2|b+D adds the diameter's default
tolerance (calib_core.solve.scale.DEFAULT_DIAMETER_SIGMA_M, relative, on every range) to the
variance, as the solver's prior on the scale does (an upper bound on what the diameter could
explain: the synthetic diameters are exact, and the solver puts the tolerance on the scale,
common to all ranges, not on each range). ``--recompute`` adds, in quadrature, the outline's
shared floor (:func:`calib_core.detect.image.apparent_range.outline_range_floor_m` of the stored range,
apparent radius and edge RMS) to each cached sigma: valid for detections cached before that
floor existed (bench_stated_cov.py's caches of 2026-11-24), what the current detector states
on the same fits.
"""

from __future__ import annotations

import argparse
import pickle
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._table import print_table  # noqa: E402
from calib_core.detect.image.fit import SHARP_EDGE_WIDTH_PX  # noqa: E402
from calib_core.detect.image.apparent_range import outline_range_floor_m  # noqa: E402
from calib_core.session import load_session  # noqa: E402
from calib_core.solve.scale import DEFAULT_DIAMETER_SIGMA_M  # noqa: E402
from calib_core.synth.ground_truth import load_ground_truth  # noqa: E402
from calib_core.synth.presets import get_preset  # noqa: E402

DEFAULT_ROOTS = ["/tmp/s3", "/tmp/s3/e2e", "/tmp/s3/full"]
PARTIAL_COVERAGE = 0.9


def _sessions(roots):
    for r in roots:
        for root in sorted(Path(r).glob("*")):
            pk = next((root / n for n in ("dets.pkl", "solver3_dets.pkl") if (root / n).is_file()), None)
            if pk is not None and (root / "ground_truth.yaml").is_file():
                yield root, pk


def _classes(preset, entry) -> list[str]:
    """Every class a detection belongs to (one row each in the table)."""
    out = ["all"]
    out.append("look" if "prediction_uv_px" in entry else "free search")
    width = entry.get("edge_width_px")
    out.append("blurred" if width is not None and np.isfinite(width) and width > SHARP_EDGE_WIDTH_PX else "sharp")
    cov = entry.get("outline_coverage", entry.get("support"))
    if cov is not None and cov < PARTIAL_COVERAGE:
        out.append("partial outline")
    out.append("photographic" if preset.photo else "plain render")
    out.append("solid ball" if preset.solid_ball else "mesh sphere")
    return out


def _rows(root: Path, pk: Path, recompute: bool):
    """(class list, session/camera key, error m, sigma m, regressor m/px, range m, diameter m) per right detection."""
    gt = load_ground_truth(root)
    dets = pickle.loads(pk.read_bytes())
    s = load_session(root)
    preset = get_preset(gt["preset"])
    ratio = gt["session_diameter_m"] / gt["sphere_diameter_m"]
    radius_m = 0.5 * gt["session_diameter_m"]
    fx = {c: s.camera_model(c).fx for c in s.cameras}
    out = []
    for cap, e in dets.items():
        g = gt["captures"].get(cap)
        for cam, v in e.items():
            if g is None or cam == "sonar" or v.get("center") is None or not v.get("range_sigma_m"):
                continue
            t = g["images"].get(cam)
            if t is None or t.get("center_uv_px") is None or np.hypot(*(np.asarray(v["center"]) - t["center_uv_px"])) > 3:
                continue
            d = t["distance_m"] * ratio
            sig = v["range_sigma_m"]
            if recompute:
                sig = float(np.hypot(sig, outline_range_floor_m(v["range_m"], v["radius_px"], v["edge_rms_px"])))
            out.append((_classes(preset, v), f"{root.name}/{cam}", v["range_m"] - d, sig,
                        -d * d / (radius_m * fx[cam]), d, gt["session_diameter_m"]))
    return out


def _debias(rows):
    """z^2 after each camera's weighted least-squares outline bias; dof-corrected."""
    z2b = np.empty(len(rows))
    keys = np.array([r[1] for r in rows])
    e = np.array([r[2] for r in rows])
    s = np.array([r[3] for r in rows])
    g = np.array([r[4] for r in rows])
    for k in np.unique(keys):
        m = keys == k
        w = 1.0 / s[m] ** 2
        b = np.sum(w * g[m] * e[m]) / np.sum(w * g[m] ** 2)
        n = m.sum()
        z2b[m] = ((e[m] - b * g[m]) / s[m]) ** 2 * (n / (n - 1) if n > 1 else np.nan)
    return z2b


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--roots", nargs="+", default=DEFAULT_ROOTS)
    ap.add_argument("--recompute", action="store_true")
    a = ap.parse_args(argv)
    rows = [r for root, pk in _sessions(a.roots) for r in _rows(root, pk, a.recompute)]
    if not rows:
        print("bench_range_sigma: no cached sessions under", " ".join(a.roots), "- skipped")
        return 0
    e = np.array([r[2] for r in rows])
    s = np.array([r[3] for r in rows])
    dia = np.array([r[5] * DEFAULT_DIAMETER_SIGMA_M / r[6] for r in rows])
    z2, z2b = (e / s) ** 2, _debias(rows)
    z2bd = z2b * s ** 2 / (s ** 2 + dia ** 2)
    table = []
    names = ["all", "free search", "look", "sharp", "blurred", "partial outline", "plain render",
             "photographic", "mesh sphere", "solid ball"]
    for c in names:
        m = np.array([c in r[0] for r in rows])
        if not m.any():
            continue
        ok = m & np.isfinite(z2b)
        table.append([c, int(m.sum()), f"{np.mean(z2[m]):.2f}", f"{np.median(z2[m]):.2f}",
                      f"{np.mean(z2b[ok]):.2f}", f"{np.median(z2b[ok]):.2f}", f"{np.mean(z2bd[ok]):.2f}",
                      f"{1e3 * np.median(s[m]):.1f}", f"{1e3 * np.sqrt(np.mean(e[m] ** 2)):.1f}"])
    print(f"Image range sigma vs truth ({len({r[1] for r in rows})} session-cameras, "
          f"{'recomputed' if a.recompute else 'as cached'})")
    print_table(["class", "n", "z2", "med z2", "z2|b", "med z2|b", "z2|b+D", "med sigma mm", "rms err mm"], table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
