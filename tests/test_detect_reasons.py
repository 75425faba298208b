"""Operator-readable detection problems (calib_core.detect.reasons)."""

from calib_core.detect.reasons import count_reasons, entry_problem, reason_kind, residual_problem


def test_reason_kind_drops_numbers_and_places():
    assert reason_kind("outline 40 % hidden or too faint at (12, 34)") == "outline % hidden or too faint"
    assert reason_kind("two round objects: (1, 2) and (3, 4)") == "two round objects"
    assert reason_kind("image: sphere cut by the image border") == "image: sphere cut by the image border"
    assert reason_kind("image: outline not round (edge RMS 2.9 px) at (609, 125)") == "image: outline not round (edge RMS px)"


def test_entry_and_residual_problems():
    assert entry_problem("k1", {"status": "auto", "reason": "no round outline"}) == "k1: no round outline"
    assert entry_problem("k1", {"status": "auto"}) == "k1: not found"
    assert entry_problem("k1", {"status": "rejected", "center": [1, 2]}) == "k1: rejected by the operator"
    assert entry_problem("k1", {"status": "auto", "center": [1, 2]}) is None
    assert entry_problem("k1", None) is None
    assert residual_problem("k1", [3.0, 2.0]) is None
    assert residual_problem("k1", [389.0, 0.0]).startswith("k1: detection 389 px from")


def test_count_reasons():
    s = count_reasons(["image: no round outline", "image: no round outline",
                       "image: two round objects: (1, 2) and (3, 4)", ""])
    assert s == "image: no round outline: 2, image: two round objects: 1"


def test_the_reason_column_says_why_missing_or_how_a_look_alike_was_ruled_out():
    from calib_core.detect.reasons import entry_note

    assert entry_note({"status": "auto", "reason": "no round outline"}) == "no round outline"
    settled = {"status": "auto", "center": [1.0, 2.0, 3.0], "resolved_by": "static scenery: the other candidate ..."}
    assert entry_note(settled) == "chosen by static scenery: the other candidate ..."
    assert entry_note({"status": "auto", "center": [1.0, 2.0]}) == ""
    assert entry_note(None) == ""


def test_a_cloud_in_millimetres_is_named_as_such():
    import numpy as np

    from calib_core.detect.reasons import cloud_units_reason

    rng = np.random.default_rng(0)
    P_m = rng.uniform([-2, -1, 0.5], [2, 1, 6], (5000, 3))  # a lab scan in metres
    assert cloud_units_reason(P_m, 0.3) is None
    assert cloud_units_reason(P_m * 20, 0.3) is None  # a far LiDAR scene is still metres
    r = cloud_units_reason(P_m * 1000, 0.3)
    assert r is not None and "millimetres" in r and "metres" in r
    assert cloud_units_reason(np.zeros((0, 3)), 0.3) is None
