"""What a fresh ``sonarcal calibrate`` imports: neither open3d (about a second) nor scipy.stats
(0.3 CPU-s) is needed to detect and solve, and the fresh calibrate's 3 s target
(benchmarks/bench_calibrate_speed.py) has no room for them."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from conftest import build_session

ROOT = Path(__file__).resolve().parents[1]
PROBE = ("import sys; from sonarcal_cli.main import main; rc = main(sys.argv[1:]); "
         "print('HEAVY=' + ','.join(m for m in ('open3d', 'scipy.stats') if m in sys.modules)); "
         "print('DETECTORS=' + str('calib_core.detect.image.limb' in sys.modules and "
         "'calib_core.detect.sonar.detect' in sys.modules)); "
         "print('RC=' + str(rc))")


def test_fresh_calibrate_imports_neither_open3d_nor_scipy_stats(tmp_path):
    root = build_session(tmp_path, n_captures=6, cameras=("cam1", "cam2"), background=True)
    env = dict(os.environ, PYTHONPATH=str(ROOT), SONARCAL_WORKERS="1")
    p = subprocess.run([sys.executable, "-c", PROBE, "calibrate", str(root), "--quiet"], capture_output=True,
                       text=True, env=env, timeout=300)
    assert "RC=0" in p.stdout, p.stderr[-2000:]
    assert "DETECTORS=True" in p.stdout  # the detectors ran (image and sonar)
    assert "HEAVY=\n" in p.stdout, p.stdout[-2000:]


def test_lopsided_threshold_is_scipy_stats_chi2_quantile():
    from scipy.stats import chi2

    from calib_core.detect.image.limb import LOPSIDED_ORDERS, LOPSIDED_SIGNIFICANCE, LOPSIDED_SIGNIFICANCE_CHI2

    assert LOPSIDED_SIGNIFICANCE_CHI2 == float(chi2.ppf(LOPSIDED_SIGNIFICANCE, 2 * len(LOPSIDED_ORDERS)))


def test_calibrate_after_detect_imports_no_detector_and_no_scipy_optimize(tmp_path):
    """Right after ``detect`` the entries are reused: no detector, nor scipy.optimize or
    scipy.spatial (0.3-0.5 s each of the 1.0 s target), is imported on the way to the solve."""
    root = build_session(tmp_path, n_captures=6, cameras=("cam1", "cam2"), background=True)
    env = dict(os.environ, PYTHONPATH=str(ROOT), SONARCAL_WORKERS="1")
    probe = PROBE.replace("('open3d', 'scipy.stats')", "('open3d', 'scipy.stats', 'scipy.optimize', 'scipy.spatial')")
    p = subprocess.run([sys.executable, "-c", probe, "detect", str(root)], capture_output=True, text=True, env=env,
                       timeout=300)
    assert "RC=0" in p.stdout, p.stderr[-2000:]
    p = subprocess.run([sys.executable, "-c", probe, "calibrate", str(root), "--quiet"], capture_output=True,
                       text=True, env=env, timeout=300)
    assert "RC=0" in p.stdout, p.stderr[-2000:]
    assert "DETECTORS=False" in p.stdout, p.stdout[-2000:]
    assert "HEAVY=\n" in p.stdout, p.stdout[-2000:]
