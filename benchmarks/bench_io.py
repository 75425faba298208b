"""I/O benchmark: load time and peak memory for 1M-point clouds in every format, and
synthetic-session generation time per capture.

    .venv/bin/python benchmarks/bench_io.py [--points 1000000] [--synth quick] [--no-synth]

Each load runs in its own process; memory is the process's RSS (which sees C allocations,
unlike tracemalloc). "peak MB" is the peak RSS during the load; "+MB" is that peak minus
the RSS just before it (interpreter and readers already imported). On a shared machine
wall time varies with load: "CPU s" (this process's CPU time) is steadier; Mpts/s uses it.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from calib_core.io.clouds import Cloud, save_cloud  # noqa: E402

CHILD = r"""
import json, resource, sys, time
from calib_core.io.clouds import load_cloud
path = sys.argv[1]
if path.endswith((".ply", ".pcd")):
    import open3d  # noqa: F401  (import cost is not load cost)
if path.endswith((".las", ".laz")):
    import laspy  # noqa: F401


def status_kb(key):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1])
    return None


try:  # Linux: reset the peak-RSS mark so the imports' peak does not hide the load's
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")
    base = status_kb("VmRSS")
except OSError:
    base = None
t, c0 = time.perf_counter(), time.process_time()
c = load_cloud(path)
dt, cpu = time.perf_counter() - t, time.process_time() - c0
peak = status_kb("VmHWM") if base is not None else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"s": dt, "cpu": cpu, "peak_kb": peak, "grow_kb": None if base is None else peak - base,
                  "n": len(c), "intensity": c.intensity is not None}))
"""


def write_cases(folder: Path, n: int) -> list[tuple[str, Path]]:
    rng = np.random.default_rng(0)
    pts = rng.uniform([-10, -10, 0.5], [10, 10, 30], size=(n, 3))
    cloud = Cloud(pts, rng.uniform(0, 255, n).round())
    cases = []
    for label, name in [("ply (binary)", "c.ply"), ("pcd (binary)", "c.pcd"), (".xyz", "c.xyz"), (".csv", "c.csv"),
                        (".npy", "c.npy"), (".las", "c.las"), (".laz", "c.laz")]:
        save_cloud(folder / name, cloud)
        cases.append((label, folder / name))
    import open3d as o3d

    t = o3d.t.geometry.PointCloud(o3d.core.Tensor(pts.astype(np.float32)))
    t.point.intensity = o3d.core.Tensor(cloud.intensity.astype(np.float32)[:, None])
    for label, name in [("ply (ascii, open3d)", "a.ply"), ("pcd (ascii, open3d)", "a.pcd")]:
        o3d.t.io.write_point_cloud(str(folder / name), t, write_ascii=True)
        cases.append((label, folder / name))
    return cases


def run_case(path: Path, repeats: int) -> dict:
    best = None
    for _ in range(repeats):
        r = subprocess.run([sys.executable, "-c", CHILD, str(path)], capture_output=True, text=True, cwd=ROOT, check=True)
        res = json.loads(r.stdout.strip().splitlines()[-1])
        if best is None or res["cpu"] < best["cpu"]:
            best = res
    return best


def bench_synth(preset: str, seed: int = 1) -> tuple[int, float] | None:
    try:
        from calib_core.synth.generate import generate_session
    except ImportError:
        return None
    from calib_core.session import load_session

    with tempfile.TemporaryDirectory() as d:
        t, c0 = time.perf_counter(), time.process_time()
        root = generate_session(Path(d) / "s", preset, seed)
        dt, cpu = time.perf_counter() - t, time.process_time() - c0
        n = len(load_session(root).captures)
    return n, dt, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--repeats", type=int, default=2, help="runs per format (the lowest CPU time is reported)")
    ap.add_argument("--synth", default="quick", help="synth preset to time (default quick)")
    ap.add_argument("--no-synth", action="store_true")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as d:
        cases = write_cases(Path(d), args.points)
        print(f"Cloud loading, {args.points:,} points with intensity (best of {args.repeats}, one process per run)\n")
        print(f"{'format':<22}{'file MB':>9}{'wall s':>8}{'CPU s':>8}{'Mpts/s':>8}{'peak MB':>9}{'+MB':>7}  intensity")
        for label, path in cases:
            r = run_case(path, args.repeats)
            assert r["n"] == args.points, (label, r)
            grow = "?" if r["grow_kb"] is None else f"{r['grow_kb'] / 1024:.0f}"
            print(f"{label:<22}{path.stat().st_size / 1e6:>9.1f}{r['s']:>8.2f}{r['cpu']:>8.2f}"
                  f"{args.points / r['cpu'] / 1e6:>8.2f}{r['peak_kb'] / 1024:>9.0f}{grow:>7}  "
                  f"{'yes' if r['intensity'] else 'no'}")
    if not args.no_synth:
        res = bench_synth(args.synth)
        if res is None:
            print("\nsynth: calib_core.synth.generate not available")
        else:
            n, dt, cpu = res
            print(f"\nsynth preset '{args.synth}': {n} captures in {dt:.1f} s wall, {cpu:.1f} s CPU = "
                  f"{dt / n:.2f} s wall, {cpu / n:.2f} s CPU per capture (rendering, sonar ray casting, writing)")


if __name__ == "__main__":
    main()
