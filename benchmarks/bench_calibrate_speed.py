"""Speed of ``sonarcal calibrate``: right after ``detect`` (detections reused by fingerprint),
fresh (detection included, in parallel processes), and the workbench's Solve (in process).

    .venv/bin/python benchmarks/bench_calibrate_speed.py [--cache DIR] [--reps 3] [--other-code DIR]

A. The synthetic "canal" preset (two 1920x1080 cameras, 9 captures, seed 1), generated once
   (kept in --cache). ``sonarcal detect`` is run, then ``sonarcal calibrate`` is timed as a
   subprocess (start-up included); then detections.yaml is removed and a fresh ``sonarcal
   calibrate`` is timed; then ``calibrate_session`` in process on the reused detections (what
   the workbench's Solve runs after the first detection).
B. 100 captures, two cameras: detections.yaml holds ``auto`` entries written the way
   ``detect`` writes them (fingerprints of the files in the session), from synthetic
   correspondences (calib_core.solve.simulate); the image and cloud files are small stand-ins
   (with matching fingerprints only their time stamps and sizes are looked at). ``sonarcal
   calibrate`` is timed as a subprocess.
Each subprocess also reports whether open3d got imported on the way. The machine is shared:
the load average is printed with every table, and CPU seconds beside every wall time. The fresh
calibrate is also run in process, where the calling thread's CPU seconds are told apart from the
process's (the second thread decodes images, :mod:`calib_core.prefetch`). ``--other-code DIR``
runs the fresh ``sonarcal calibrate`` also with another checkout's code (e.g. main's, from
``git worktree add`` or ``git archive``), interleaved with this one's: before and after on the
same machine state.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks._machine import machine_line  # noqa: E402
from benchmarks._table import print_targets  # noqa: E402

PROBE = ("import sys, runpy; sys.argv = ['sonarcal'] + sys.argv[1:]; "
         "from sonarcal_cli.main import main; rc = main(sys.argv[1:]); "
         "print('OPEN3D_IMPORTED=' + str('open3d' in sys.modules), file=sys.stderr); sys.exit(rc)")


def cli(*args, code: Path = ROOT, **extra_env) -> tuple[float, bool, float]:
    """(wall s, open3d imported, CPU s of the process and its children: user + sys), running the
    code in ``code``."""
    import resource

    env = dict(os.environ, PYTHONPATH=str(code), **extra_env)
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    # cwd: "python -c" puts the working directory first on sys.path, before PYTHONPATH
    p = subprocess.run([sys.executable, "-c", PROBE, *args], capture_output=True, text=True, env=env, cwd=str(code))
    dt = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        raise RuntimeError(f"sonarcal {' '.join(args)} failed: {p.stderr[-2000:]}")
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    return dt, "OPEN3D_IMPORTED=True" in p.stderr, cpu


def fresh_in_process(root: Path, reps: int) -> list[tuple[float, float, float]]:
    """[(wall s, process CPU s, calling thread's CPU s)] of a fresh calibrate_session in process."""
    from calib_core.detections import load_detections
    from calib_core.session import load_session
    from calib_core.solve.calibrate import calibrate_session

    out = []
    for _ in range(reps):
        (root / "detections.yaml").unlink(missing_ok=True)
        s = load_session(root)
        t0, c0, h0 = time.perf_counter(), time.process_time(), time.thread_time()
        calibrate_session(s, load_detections(s), {"detect": True})
        out.append((time.perf_counter() - t0, time.process_time() - c0, time.thread_time() - h0))
    return out


def part_a(cache: Path, reps: int, other: Path | None = None):
    from calib_core.detections import load_detections
    from calib_core.session import load_session
    from calib_core.solve.calibrate import calibrate_session
    from calib_core.synth.generate import generate_session

    src = cache / "canal-1"
    if not (src / "session.yaml").exists():
        generate_session(src, "canal", 1)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "s"
        shutil.copytree(src, root)
        (root / "detections.yaml").unlink(missing_ok=True)
        t_det = cli("detect", str(root))[0]
        after = [cli("calibrate", str(root), "--quiet") for _ in range(reps)]
        s = load_session(root)
        dets = load_detections(s)
        calibrate_session(s, dets)  # warm (imports)
        solve = []
        for _ in range(reps):
            t0 = time.perf_counter()
            calibrate_session(s, load_detections(s))
            solve.append(time.perf_counter() - t0)
        fresh, pooled, others = [], [], []
        for _ in range(reps):  # interleaved: the machine's other jobs hit both alike
            (root / "detections.yaml").unlink(missing_ok=True)
            fresh.append(cli("calibrate", str(root), "--quiet"))
            (root / "detections.yaml").unlink(missing_ok=True)
            pooled.append(cli("calibrate", str(root), "--quiet", SONARCAL_WORKERS="2"))
            if other is not None:
                (root / "detections.yaml").unlink(missing_ok=True)
                others.append(cli("calibrate", str(root), "--quiet", code=other))
        in_process = fresh_in_process(root, reps)
    return t_det, after, fresh, solve, pooled, others, in_process


def fresh_pairs(cache: Path, n: int, other: Path | None) -> None:
    """The fresh calibrate of canal-1 with this code and ``other``'s, alternately ``n`` times each
    (a subprocess each): per run wall and CPU s, then the medians and minima."""
    from benchmarks._table import print_table
    from calib_core.synth.generate import generate_session

    src = cache / "canal-1"
    if not (src / "session.yaml").exists():
        generate_session(src, "canal", 1)
    codes = [("this", ROOT)] + ([(str(other), other)] if other else [])
    runs: dict = {name: [] for name, _ in codes}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "s"
        shutil.copytree(src, root)
        for _ in range(n):
            for name, code in codes:
                (root / "detections.yaml").unlink(missing_ok=True)
                wall, _, cpu = cli("calibrate", str(root), "--quiet", code=code)
                runs[name].append((wall, cpu, os.getloadavg()[0]))
                print(f"  {name}: wall {wall:.2f} s, CPU {cpu:.2f} s, load {runs[name][-1][2]:.1f}", flush=True)
    rows = [[name, " ".join(f"{c:.2f}" for _, c, _ in r), f"{statistics.median(c for _, c, _ in r):.2f}",
             f"{min(c for _, c, _ in r):.2f}", f"{statistics.median(w for w, _, _ in r):.2f}",
             f"{min(w for w, _, _ in r):.2f}"] for name, r in runs.items()]
    print_table(["code", "CPU s per run", "CPU median", "CPU min", "wall median", "wall min"], rows)


def synthetic_session(root: Path, n: int):
    """A 2-camera session with n captures and auto entries carrying detect's fingerprints."""
    from calib_core.detections import save_detections
    from calib_core.io.intrinsics import save_intrinsics_ros
    from calib_core.pipeline import SessionData, _with_fingerprint
    from calib_core.session import load_session
    from calib_core.solve.simulate import synthetic_rig

    rig = synthetic_rig(77, n_captures=n, sigma_px=0.3, sigma_m=0.003)
    root.mkdir(parents=True)
    for c, cam in rig.cameras.items():
        save_intrinsics_ros(root / "intrinsics" / f"{c}.yaml", cam, c)
        (root / "images" / c).mkdir(parents=True)
    (root / "clouds").mkdir()
    for i in rig.capture_ids:
        (root / "clouds" / f"{i}.npy").write_bytes(os.urandom(4096))
        for c in rig.cameras:
            (root / "images" / c / f"{i}.png").write_bytes(os.urandom(4096))
    man = {"format": "sonar-camera-session/1", "name": f"speed-{n}", "sphere": {"diameter": 0.22},
           "cameras": {c: {"intrinsics": f"intrinsics/{c}.yaml"} for c in rig.cameras},
           "captures": [{"id": i, "cloud": f"clouds/{i}.npy", "images": {c: f"images/{c}/{i}.png" for c in rig.cameras}}
                        for i in rig.capture_ids],
           "stereo": {"T_cam2_cam1": rig.T_cam2_cam1.tolist()}}
    (root / "session.yaml").write_text(yaml.safe_dump(man, sort_keys=False))
    data = SessionData(load_session(root))
    dets = {}
    for k, cid in enumerate(rig.capture_ids):
        son = {"status": "auto", "center": rig.X_sonar_m[k].tolist(), "cov_m2": rig.cov_X_m2[k].ravel().tolist(),
               "beam_width_deg": 1.0, "beam_width_nominal_deg": 1.0}
        dets[cid] = {"sonar": _with_fingerprint(data, cid, "sonar", son)}
        for c in rig.cameras:
            e = {"status": "auto", "center": rig.uv_px[c][k].tolist(), "cov_px2": rig.cov_uv_px2[c][k].ravel().tolist()}
            dets[cid][c] = _with_fingerprint(data, cid, c, e)
    save_detections(data.session, dets)


def report_part_a(t_det, after, fresh, solve, pooled, others, in_process, other_code) -> list:
    """Print part A's timings; its target checks."""
    ta = statistics.median(r[0] for r in after)
    tf = statistics.median(r[0] for r in fresh)
    ts = statistics.median(solve)
    print(f"\nA. canal preset, 2 cameras 1920x1080, 9 captures; load {os.getloadavg()}")
    print(f"  sonarcal detect:                              {t_det:.2f} s")
    print(f"  sonarcal calibrate right after detect:        {ta:.2f} s  (runs {', '.join(f'{r[0]:.2f}' for r in after)}; "
          f"CPU s {', '.join(f'{r[2]:.2f}' for r in after)}; open3d imported: {after[0][1]})")
    print(f"  sonarcal calibrate fresh (detection included): {tf:.2f} s  (runs {', '.join(f'{r[0]:.2f}' for r in fresh)}; "
          f"CPU s (in process below 40 tasks: all of it) {', '.join(f'{r[2]:.2f}' for r in fresh)})")
    print(f"  the same in 2 processes (SONARCAL_WORKERS=2): {statistics.median(r[0] for r in pooled):.2f} s  "
          f"(runs {', '.join(f'{r[0]:.2f}' for r in pooled)}; CPU s of the main process {', '.join(f'{r[2]:.2f}' for r in pooled)})")
    if others:
        print(f"  the same with {other_code}: {statistics.median(r[0] for r in others):.2f} s  "
              f"(runs {', '.join(f'{r[0]:.2f}' for r in others)}; CPU s {', '.join(f'{r[2]:.2f}' for r in others)})")
    print(f"  calibrate_session in process, fresh:          {statistics.median(r[0] for r in in_process):.2f} s  "
          f"(CPU s of the process {', '.join(f'{r[1]:.2f}' for r in in_process)}; "
          f"of the calling thread {', '.join(f'{r[2]:.2f}' for r in in_process)})")
    print(f"  calibrate_session in process, reused (Solve): {ts:.2f} s  (runs {', '.join(f'{v:.2f}' for v in solve)})")
    return [("calibrate right after detect, 9 captures, <= 1.0 s", f"{ta:.2f} s", ta <= 1.0),
            ("fresh calibrate, 9 captures 1080p, <= 3 s", f"{tf:.2f} s", tf <= 3.0),
            ("workbench Solve after the first detection (calibrate_session, reused) <= 1.5 s", f"{ts:.2f} s",
             ts <= 1.5)]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", default=str(Path(tempfile.gettempdir()) / "sonarcal_speed_cache"))
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--skip-a", action="store_true")
    ap.add_argument("--other-code", type=Path, default=None,
                    help="another checkout whose fresh calibrate is timed too, interleaved (before/after)")
    ap.add_argument("--pairs", type=int, default=0,
                    help="only the fresh calibrate, this code and --other-code's alternately, this many times each")
    a = ap.parse_args(argv)
    cache = Path(a.cache)
    cache.mkdir(parents=True, exist_ok=True)
    if a.pairs:
        print(machine_line())
        return fresh_pairs(cache, a.pairs, a.other_code)
    checks = []
    print(machine_line())
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "s100"
        synthetic_session(root, 100)
        runs = [cli("calibrate", str(root), "--quiet") for _ in range(a.reps)]
    t100 = statistics.median(r[0] for r in runs)
    print(f"\nB. 100 captures x 2 cameras, detections reused: sonarcal calibrate {t100:.2f} s (median of {a.reps}; "
          f"runs {', '.join(f'{r[0]:.2f}' for r in runs)}; CPU s {', '.join(f'{r[2]:.2f}' for r in runs)}); "
          f"open3d imported: {runs[0][1]}; load {os.getloadavg()}")
    checks.append(("calibrate right after detect, 100 captures, <= 3 s (subprocess, start-up included)",
                   f"{t100:.2f} s", t100 <= 3.0))
    if not a.skip_a:
        checks += report_part_a(*part_a(cache, a.reps, a.other_code), a.other_code)
    print(f"load average after: {os.getloadavg()}")
    print_targets(checks)


if __name__ == "__main__":
    main()
