"""The ``--flow`` mode of ``bench_image_sessions.py``: image recall after the whole session flow.

For each generated session, :func:`calib_core.pipeline.detect_session` runs (the detectors, then
the sonar-guided second look), then :func:`calib_core.solve.calibrate.calibrate_session`. Each
camera image's final entry is judged against the truth ("right" within 3 px), and a wrong centre
is "used" when the solve kept that capture. The sonar entries are cached next to the session
(``.flow_sonar.json``) because they do not depend on the image side; the image entries are
always detected afresh.
"""

from __future__ import annotations

import json
import time
from collections import Counter
from pathlib import Path

import numpy as np

from calib_core.detect.reasons import reason_kind
from calib_core.pipeline import SessionData, detect_session
from calib_core.session import load_session
from calib_core.synth.ground_truth import load_ground_truth

TOL_PX = 3.0


def new_flow_stats() -> dict:
    return {"images": 0, "visible": 0, "right": 0, "right_visible": 0, "wrong": 0, "missed": 0, "used_wrong": 0, "second": 0,
            "second_right": 0, "miss_reasons": Counter(), "wrong_list": [], "miss_list": [], "s": []}


def _sonar_only(root: Path, data: SessionData) -> dict:
    """The session's sonar entries (cached in ``root/.flow_sonar.json``)."""
    cache = root / ".flow_sonar.json"
    if cache.is_file():
        return json.loads(cache.read_text())
    dets = detect_session(data, {}, workers=1)
    son = {cid: {"sonar": d["sonar"]} for cid, d in dets.items() if "sonar" in d}
    cache.write_text(json.dumps(son))
    return son


def _used(session, dets: dict) -> dict:
    """{camera: set of capture ids the solve used}; empty when it could not calibrate."""
    from calib_core.errors import SessionError
    from calib_core.solve.calibrate import calibrate_session

    try:
        cal = calibrate_session(session, dets, {"detect": False})
    except SessionError:
        return {}
    return {cam: {r["capture"] for r in c.get("residuals", []) if r.get("used")}
            for cam, c in cal["cameras"].items()}


def run_flow_session(root: Path, name: str, st: dict, listing: bool) -> None:
    """Judge every image entry of one session after the flow (into ``st``)."""
    data = SessionData(load_session(root))
    gt = load_ground_truth(root)
    t0 = time.perf_counter()
    dets = detect_session(data, _sonar_only(root, data), workers=1)
    st["s"].append(time.perf_counter() - t0)
    used = _used(data.session, dets)
    for cap in data.session.captures:
        for cam in cap.image_paths:
            e = dets.get(cap.id, {}).get(cam) or {}
            truth = gt["captures"][cap.id]["images"][cam]
            _judge(st, e, truth, cap.id in used.get(cam, set()), f"{name} {cap.id} {cam}", listing)


def _judge(st: dict, e: dict, truth: dict, used: bool, name: str, listing: bool) -> None:
    uv = truth.get("center_uv_px")
    st["images"] += 1
    st["visible"] += bool(truth.get("visible"))
    second = bool(e.get("resolved_by"))
    st["second"] += second
    if e.get("center") is not None:
        off = float(np.hypot(*(np.asarray(e["center"], float) - uv))) if uv is not None else float("nan")
        verdict = "right" if off <= TOL_PX else "wrong"
        st["second_right"] += second and verdict == "right"
        st["right_visible"] += verdict == "right" and bool(truth.get("visible"))
        if verdict == "right":
            st.setdefault("right_off", []).append(off)
        if verdict == "wrong":
            st["used_wrong"] += used
            st["wrong_list"].append(f"{name} {off:.1f} px{' (second look)' if second else ''}"
                                    f"{' USED' if used else ''}")
    elif truth.get("visible"):
        verdict = "missed"
        st["miss_reasons"][reason_kind(e.get("reason") or "")] += 1
        st["miss_list"].append(f"{name}: {e.get('reason')}")
    else:
        verdict = "ok-absent"
    st[verdict] = st.get(verdict, 0) + 1
    if listing:
        print(f"{name:32s} vis={truth.get('visible')!s:5s} {verdict:9s} {'2nd ' if second else ''}"
              f"{e.get('reason') or ''}", flush=True)


def print_flow_table(rows: dict, seeds, scale: float) -> None:
    print(f"\nImage entries after the session flow (detect_session incl. the sonar-guided second look, "
          f"then calibrate_session), seeds {seeds[0]}-{seeds[-1]}, scale {scale:g}")
    print("| preset | images | whole ball visible | right (<= 3 px; also partly hidden balls) | recall of visible | wrong | wrong used in a solve "
          "| missed (visible) | misses (reason: count) | second-look entries (right) | s/session (median) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for preset, st in rows.items():
        miss = ", ".join(f"{k}: {v}" for k, v in st["miss_reasons"].most_common()) or "-"
        rec = 100.0 * st["right_visible"] / max(st["visible"], 1)
        print(f"| {preset} | {st['images']} | {st['visible']} | {st['right']} | {rec:.1f} % | {st['wrong']} "
              f"| {st['used_wrong']} | {st['missed']} | {miss} | {st['second']} ({st['second_right']}) "
              f"| {np.median(st['s']):.1f} |")
    for preset, st in rows.items():
        off = st.get("right_off") or []
        if off:
            print(f"  {preset}: centre RMS of the right entries {np.sqrt(np.mean(np.square(off))):.3f} px "
                  f"(max {max(off):.2f}, {len(off)} entries)")
    for preset, st in rows.items():
        for w in st["wrong_list"]:
            print(f"  wrong: {w}")
        for m in st["miss_list"]:
            print(f"  missed: {m}")
