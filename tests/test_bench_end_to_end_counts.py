"""benchmarks/bench_end_to_end.py counts a capture the gate flagged as a good one only when its
image detection is right: a flagged decoy (the review preset's p04, 150 px off) is flagged rightly."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import bench_end_to_end as e2e  # noqa: E402


def _truth(uv, visible=True):
    return {"images": {"cam1": {"center_uv_px": list(uv), "visible": visible, "in_image": True,
                                "occluded_fraction": 0.0 if visible else 0.5}}}


def test_a_decoy_is_listed_wrong_and_a_right_centre_is_not():
    gt = {"captures": {"p01": _truth((100.0, 100.0)), "p02": _truth((200.0, 200.0), visible=False),
                       "p03": _truth((300.0, 300.0))}}
    dets = {"p01": {"cam1": {"center": [100.5, 100.0]}}, "p02": {"cam1": {"center": [350.0, 200.0]}},
            "p03": {"cam1": {}}}
    found, false_used, wrong = e2e.detection_counts(gt, dets, "cam1", used={"p01"})
    assert (found, false_used, wrong) == ("1/2", 0, ["p02"])
    # used, the decoy is a false detection that reached the solve
    assert e2e.detection_counts(gt, dets, "cam1", used={"p01", "p02"})[1] == 1
