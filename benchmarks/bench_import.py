"""Import benchmark (issue 15): bag round-trip accuracy, drift flags, import speed and memory.

    .venv/bin/python benchmarks/bench_import.py [--accuracy] [--speed] [--memory] [--off] [--seeds 3]
        [--big-gb 2.0] [--tmp /tmp]

accuracy: synth (drift preset; --canal adds the two-camera canal preset, whose stereo transform
travels as /tf_static) -> ROS 2 MCAP bag and ROS 1 bag -> ``sonarcal import`` ->
calibrate, against the folder session, on several seeds: pose errors versus ground truth,
the ratio to the folder's error (target <= 1.10), and which captures were flagged as moved
(target: exactly the drifting one).
speed: a bag of 20 scans of 500k points (60 PointCloud2 slices each) and 1080p frames of two
cameras, imported in a child process (target <= 60 s on 2 cores; wall and CPU time).
memory: peak RSS (VmHWM of the import process) for a ~0.5 GB and a ~2 GB bag with the same
scans (more frames per scan): bounded memory means the two peaks are about equal. The bags
are written to --tmp and deleted afterwards.
off: load time and memory growth of a 1M-point ProScan .off file (strict, chunked parse).
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from calib_core.camera import CameraModel  # noqa: E402
from calib_core.ingest import rosmsg  # noqa: E402
from calib_core.ingest.bagwrite import BagWriter  # noqa: E402

NS = 1_000_000_000


def loadavg() -> str:
    return Path("/proc/loadavg").read_text().split(" ", 3)[:3].__str__()


# ---- accuracy ----------------------------------------------------------------------------
def _errors(folder: Path, gt: dict) -> dict:
    """{camera: (rotation error deg, translation error mm)} of a calibration against the truth."""
    from calib_core.detections import load_detections
    from calib_core.geometry import pose_error
    from calib_core.session import load_session
    from calib_core.solve.calibrate import calibrate_session

    s = load_session(folder)
    cal = calibrate_session(s, load_detections(s), {"leave_one_out": False})
    out = {}
    for cam, c in cal["cameras"].items():
        r, t = pose_error(np.asarray(c["T_cam_sonar"]), np.asarray(gt["cameras"][cam]["T_cam_sonar"]))
        out[cam] = (float(np.degrees(r)), t * 1000)
    return out


def _round_trip(preset: str, seed: int, tmp: Path) -> None:
    from calib_core.session import load_session
    from calib_core.synth.bag import write_session_bag
    from calib_core.synth.generate import generate_session

    root = Path(tempfile.mkdtemp(dir=tmp, prefix="bench_import_"))
    try:
        folder = generate_session(root / "folder", preset, seed, scale=0.5)
        gt = yaml.safe_load((folder / "ground_truth.yaml").read_text())
        drift = [c for c, e in gt["captures"].items() if "drift" in e]
        base = _errors(folder, gt)
        for cam, (r0, t0) in base.items():
            print(f"| {preset} {seed} | {cam} | folder | {r0:.3f} | {t0:.1f} | 1 | - | {', '.join(drift) or 'none'} | - |")
        d = load_session(folder).sphere_diameter_m
        for kind in ("ros2", "ros1"):
            bag = write_session_bag(folder, root / ("b.bag" if kind == "ros1" else "b_ros2"), kind, seed=seed)
            out = root / f"imp_{kind}"
            subprocess.run([sys.executable, "-m", "sonarcal_cli.main", "import", str(bag), "--out", str(out),
                            "--diameter", str(d), "--background", "0:2"], check=True, capture_output=True)
            imported = load_session(out)
            moved = [c for c, e in imported.raw["target_motion"]["captures"].items() if e["moved"]]
            stereo = "stereo from /tf_static" if imported.stereo else ""
            for cam, (r1, t1) in _errors(out, gt).items():
                r0, t0 = base[cam]
                ok = max(r1 / r0, t1 / t0) <= 1.10 and moved == drift
                print(f"| {preset} {seed} | {cam} | {kind} bag {stereo} | {r1:.3f} | {t1:.1f} | {r1 / r0:.3f} / "
                      f"{t1 / t0:.3f} | {', '.join(moved) or 'none'} | {', '.join(drift) or 'none'} | "
                      f"{'met' if ok else 'MISSED'} |")
    finally:
        shutil.rmtree(root, ignore_errors=True)


def accuracy(seeds: list[int], tmp: Path, canal: bool) -> None:
    print("\n### Bag round trip: synth (scale 0.5) -> bag -> import -> calibrate")
    print("| preset seed | camera | source | rot err deg | trans err mm | ratio to folder (rot / trans) | flagged | "
          "drifting | target |")
    print("|---|---|---|---|---|---|---|---|---|")
    for seed in seeds:
        _round_trip("drift", seed, tmp)
    if canal:
        _round_trip("canal", 1, tmp)
    print(f"\nload average: {loadavg()}")


# ---- big bags ------------------------------------------------------------------------------
def _frame(cam: CameraModel, rng, u: float) -> np.ndarray:
    import cv2

    img = np.full((cam.height_px, cam.width_px, 3), 150, np.uint8)
    cv2.circle(img, (int(u), cam.height_px // 2), 60, (40, 40, 40), -1, lineType=cv2.LINE_AA)
    return np.clip(img + rng.normal(0, 2, img.shape), 0, 255).astype(np.uint8)


def write_big_bag(path: Path, n_scans: int, points: int, frames_per_scan: int, n_cams: int = 2,
                  slices: int = 60, kind: str = "ros1") -> float:
    """A field-like bag: pans of ``slices`` PointCloud2 slices, ``frames_per_scan`` rgb8 1080p frames
    per camera and scan, CameraInfo with each frame. Returns its size in GB."""
    rng = np.random.default_rng(0)
    cam = CameraModel(1920, 1080, [[1400, 0, 960], [0, 1400, 540], [0, 0, 1]])
    frames = [_frame(cam, rng, 900 + 4 * i) for i in range(4)]  # a few distinct frames, reused
    cloud = rng.normal(0, 2, (points, 3)) + [4, 0, 0]
    inten = rng.random(points)
    with BagWriter(path, kind) as w:
        ts, r1 = w.typestore, w.ros1
        for k in range(n_scans):
            t0 = 5 + k * 70
            for i, idx in enumerate(np.array_split(np.arange(points), slices)):
                t = int((t0 + (i + 0.5) * 60 / slices) * NS)
                w.write("/sonar/points", rosmsg.POINTCLOUD2, t, rosmsg.cloud_msg(ts, t, "sonar", cloud[idx], inten[idx], r1))
            for c in range(n_cams):
                for j in range(frames_per_scan):
                    t = int((t0 + (j + 0.5) * 60 / frames_per_scan) * NS) + c
                    w.write(f"/cam{c + 1}/image_raw", rosmsg.IMAGE, t,
                            rosmsg.image_msg(ts, t, f"cam{c + 1}", frames[j % len(frames)], r1))
                    w.write(f"/cam{c + 1}/camera_info", rosmsg.CAMERA_INFO, t, rosmsg.info_msg(ts, t, f"cam{c + 1}", cam, r1))
    size = sum(p.stat().st_size for p in ([path] if path.is_file() else path.iterdir()))
    return size / 1e9


def run_import(bag: Path, out: Path) -> dict:
    """Import in a child process; wall time, CPU time and peak RSS (VmHWM, polled)."""
    cmd = [sys.executable, "-m", "sonarcal_cli.main", "import", str(bag), "--out", str(out), "--diameter", "0.25"]
    before, t = os.times(), time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    hwm = 0
    while p.poll() is None:
        try:
            with open(f"/proc/{p.pid}/status") as f:
                for line in f:
                    if line.startswith("VmHWM:"):
                        hwm = max(hwm, int(line.split()[1]))
        except OSError:
            pass
        time.sleep(0.1)
    wall = time.perf_counter() - t
    out_s, err = p.communicate()
    if p.returncode != 0:
        raise RuntimeError(f"import failed: {err.decode()[-500:]}")
    after = os.times()  # children's CPU time counts once they are waited for
    cpu = after.children_user + after.children_system - before.children_user - before.children_system
    return {"wall_s": wall, "cpu_s": cpu, "peak_mb": hwm / 1024,
            "captures": out_s.decode().count(", ") + 1}


def speed(tmp: Path) -> None:
    print("\n### Import speed: 20 scans x 500k points (60 slices each), 2 cameras of 1080p rgb8 frames")
    print("| frames per camera | bag GB | wall s | CPU s | peak RSS MB | target <= 60 s |")
    print("|---|---|---|---|---|---|")
    for fps in (1, 5):
        root = Path(tempfile.mkdtemp(dir=tmp, prefix="bench_import_"))
        try:
            gb = write_big_bag(root / "big.bag", 20, 500_000, fps)
            r = run_import(root / "big.bag", root / "out")
            print(f"| {20 * fps} ({fps} per scan) | {gb:.2f} | {r['wall_s']:.1f} | {r['cpu_s']:.1f} | {r['peak_mb']:.0f} | "
                  f"{'met' if r['wall_s'] <= 60 else 'MISSED'} |")
        finally:
            shutil.rmtree(root, ignore_errors=True)
    print(f"\nload average: {loadavg()}")


def memory(tmp: Path, big_gb: float) -> None:
    print("\n### Import memory: same 20 scans x 500k points, more frames per scan -> bigger bag")
    print("| bag GB | frames per camera and scan | peak RSS MB | wall s |")
    print("|---|---|---|---|")
    per_frame_gb = 2 * 1920 * 1080 * 3 / 1e9 * 20  # two cameras, 20 scans
    for gb_target in (0.5, big_gb):
        fps = max(1, round((gb_target - 0.17) / per_frame_gb))
        root = Path(tempfile.mkdtemp(dir=tmp, prefix="bench_import_"))
        try:
            gb = write_big_bag(root / "big.bag", 20, 500_000, fps)
            r = run_import(root / "big.bag", root / "out")
            print(f"| {gb:.2f} | {fps} | {r['peak_mb']:.0f} | {r['wall_s']:.1f} |")
        finally:
            shutil.rmtree(root, ignore_errors=True)
    print(f"\nload average: {loadavg()}")


OFF_CHILD = r"""
import sys, time
from calib_core.io.clouds import load_cloud
def hwm():
    return int(next(l for l in open("/proc/self/status") if l.startswith("VmHWM:")).split()[1]) / 1024
before = hwm(); t = time.perf_counter(); c = load_cloud(sys.argv[1]); dt = time.perf_counter() - t
print(len(c), dt, hwm() - before)
"""


def off_files(tmp: Path, n: int = 1_000_000) -> None:
    """ProScan .off load time and memory growth (a child process per load)."""
    print(f"\n### ProScan .off: {n} points (X Y Z R G B A rows)")
    print("| file MB | load s | memory growth MB | points/s |")
    print("|---|---|---|---|")
    rng = np.random.default_rng(0)
    path = Path(tempfile.mkdtemp(dir=tmp, prefix="bench_import_")) / "scan.off"
    try:
        pts = rng.normal(0, 3, (n, 3))
        g = rng.integers(0, 256, n)
        arr = np.column_stack([pts, g, g, g, np.full(n, 255)])
        with open(path, "w") as f:
            f.write(f"OFF\n{n} 0 0\n")
            np.savetxt(f, arr, fmt=["%.4f"] * 3 + ["%d"] * 4)
        out = subprocess.run([sys.executable, "-c", OFF_CHILD, str(path)], capture_output=True, text=True, check=True,
                             env=dict(os.environ, PYTHONPATH=str(ROOT))).stdout.split()
        k, dt, grow = int(out[0]), float(out[1]), float(out[2])
        print(f"| {path.stat().st_size / 1e6:.0f} | {dt:.2f} | {grow:.0f} | {k / dt / 1e6:.2f} M |")
    finally:
        shutil.rmtree(path.parent, ignore_errors=True)
    print(f"\nload average: {loadavg()}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--accuracy", action="store_true")
    ap.add_argument("--speed", action="store_true")
    ap.add_argument("--memory", action="store_true")
    ap.add_argument("--off", action="store_true", help="ProScan .off load time and memory")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--canal", action="store_true", help="accuracy: also the two-camera canal preset (stereo)")
    ap.add_argument("--big-gb", type=float, default=2.0)
    ap.add_argument("--tmp", default=tempfile.gettempdir())
    a = ap.parse_args()
    every = not (a.accuracy or a.speed or a.memory or a.off)
    tmp = Path(a.tmp)
    if a.accuracy or every:
        accuracy(list(range(1, a.seeds + 1)), tmp, a.canal)
    if a.speed or every:
        speed(tmp)
    if a.memory or every:
        memory(tmp, a.big_gb)
    if a.off or every:
        off_files(tmp)


if __name__ == "__main__":
    main()
