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
