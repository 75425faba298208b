"""benchmarks/bench_scale_stereo_default.py reproduces both columns of its BENCHMARKS.md table:
``--no-widen`` (the stereo covariance as stated) must run against solve_rig as it is now."""

from __future__ import annotations

import sys
from pathlib import Path

import calib_core.solve.rig as rig_module

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import bench_scale_stereo_default as bench  # noqa: E402


def test_the_no_widen_variant_runs_and_widens_nothing(monkeypatch, capsys):
    monkeypatch.setattr(rig_module, "stereo_factor", rig_module.stereo_factor)  # restored after the test
    bench.main(["--trials", "1", "--no-widen"])
    out = capsys.readouterr().out
    assert out.startswith("before (no widening)")
    assert sum(line.startswith(("0.05/1 |", "0.08/2 |")) for line in out.splitlines()) == 4
    assert rig_module.stereo_factor is bench.stereo_as_stated


def test_bench_end_to_end_before_stands_in_for_the_stereo_factor(monkeypatch):
    """``bench_end_to_end.py --before`` (no stereo variance factor) must run with solve_rig as it is
    now: its stand-in returned no scale-free fit, which solve_rig reads (systematic term, scale test)."""
    import bench_end_to_end as e2e

    from calib_core.solve.model import camera_data
    from calib_core.solve.refine import Link
    from calib_core.solve.simulate import synthetic_rig
    from calib_core.solve.single import solve_camera

    rig = synthetic_rig(21, n_captures=8, scale=1.0, sigma_px=0.1, sigma_m=0.001)
    sols = {c: solve_camera(camera_data(c, rig.cameras[c], rig.capture_ids, rig.uv_px[c], rig.cov_uv_px2[c],
                                        rig.X_sonar_m, rig.cov_X_m2), estimate_scale=False, loo=False)
            for c in ("cam1", "cam2")}
    monkeypatch.setattr(rig_module, "stereo_factor", e2e.stereo_as_stated)
    rs = rig_module.solve_rig(sols, {"cam2": Link(rig.T_cam2_cam1, rig_module.default_stereo_cov())}, "cam1")
    assert rs.stereo_factor["factor"] == 1.0 and rs.scale == 1.0
