"""The static-scenery cue's shares measured on dumped sweep entries (``bench_sonar_choice.py --entries``).

Reads the JSON files ``bench_detection_range.py --sweep --dump DIR`` writes (one per session:
every capture's sonar entry and its truth) and settles, offline, each capture that records two
or more round objects of the sphere's size, for a grid of (STATIC_SHARE, MOVING_SHARE):

1. "two candidates" refusals (:func:`calib_core.disambiguate.sonar.choose_by_scenery`);
2. clear winners and what they beat, as :func:`calib_core.disambiguate.sonar.reexamine_winners`
   does without images (the sweep renders none).

Counts per pair: settled right (the candidate taken is within a radius of the truth), wrong,
and left as they were. A capture without a target that gets settled counts as wrong.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from calib_core.disambiguate.sonar import MOVING_SHARE, STATIC_SHARE, choose_by_scenery, sightings_sonar_m

STATIC_GRID = (0.2, 0.25, 0.3, 0.4, 0.5, 0.6)
MOVING_GRID = (0.1, 0.15, 0.2, 0.3)


def _cases(paths: list[Path]) -> list[dict]:
    """Every capture recording >= 2 sightings: candidates (row 0 = the winner for a clear
    winner), kind, index of the truth among them (None: none is), the others' sightings."""
    out = []
    for f in sorted(p for d in paths for p in Path(d).glob("*.json")):
        sess = json.loads(f.read_text())
        r, caps = float(sess["radius_m"]), sess["captures"]
        sights = {cid: sightings_sonar_m(c["sonar"]) for cid, c in caps.items()}
        for cid, c in caps.items():
            e = c["sonar"]
            if e.get("center") is None and e.get("two_candidates"):
                kind, cands = "two", np.asarray(e["two_candidates"], float)
            elif e.get("center") is not None and e.get("other_candidates"):
                kind, cands = "winner", np.asarray([e["center"], *e["other_candidates"]], float)
            else:
                continue
            truth = None
            if c["target"] and c["truth"] is not None:
                d = np.linalg.norm(cands - np.asarray(c["truth"], float), axis=1)
                truth = int(np.argmin(d)) if d.min() <= r else None
            out.append({"session": f.stem, "cid": cid, "kind": kind, "cands": cands, "truth": truth, "r": r,
                        "evidence": e.get("candidate_evidence"),
                        "others": {o: s for o, s in sights.items() if o != cid}})
    return out


def _settle(case: dict, static: float, moving: float) -> str:
    """"right", "wrong" or "left" for one case and one pair of shares."""
    k, _ = choose_by_scenery(case["cands"], case["others"], case["r"], static, moving)
    if case["kind"] == "winner" and not k:  # kept the winner (as the pipeline does)
        return "left"
    if k is None:
        return "left"
    return "right" if k == case["truth"] else "wrong"


def shares_tables(paths: list[Path]) -> None:
    cases = _cases(paths)
    evidence_table(cases)
    wrong_centres(paths, cases)
    for kind, title in (("two", "\"two candidates\" refusals"), ("winner", "clear winners re-examined")):
        sub = [c for c in cases if c["kind"] == kind]
        n_truth = sum(c["truth"] is not None for c in sub)
        if kind == "winner":
            n_win = sum(c["truth"] == 0 for c in sub)
            print(f"\n{title}: {len(sub)} captures; the winner is the target in {n_win}, a loser in "
                  f"{n_truth - n_win}, none of them in {len(sub) - n_truth}")
        else:
            print(f"\n{title}: {len(sub)} captures, the target among the candidates in {n_truth}")
        print("right/wrong/left; rows STATIC_SHARE, columns MOVING_SHARE (* = in use)")
        print("static " + "".join(f"{mv:>13.2f}" for mv in MOVING_GRID))
        for st in STATIC_GRID:
            row = f"{st:6.2f} "
            for mv in MOVING_GRID:
                res = [_settle(c, st, mv) for c in sub]
                mark = "*" if (st, mv) == (STATIC_SHARE, MOVING_SHARE) else " "
                row += (mark + f"{res.count('right')}/{res.count('wrong')}/{res.count('left')}").rjust(13)
            print(row)
        for c in sub:
            res = _settle(c, STATIC_SHARE, MOVING_SHARE)
            missed = c["truth"] is not None and (kind == "two" or c["truth"] > 0)
            if res != "left" or missed:
                print(f"  {c['session']} {c['cid']}: {res} (truth index {c['truth']}, "
                      f"{len(c['cands'])} candidates, {len(c['others'])} other captures)")


def evidence_table(cases: list[dict]) -> None:
    """For the "two candidates" refusals that recorded their evidence (score x size agreement x
    scatter, see calib_core.detect.sonar.detect._Judged.evidence): is the best one the target, and by
    what ratio over the second (CLEAR_WINNER = 3 takes it)."""
    rows = [c for c in cases if c["kind"] == "two" and c.get("evidence") and c["truth"] is not None]
    if not rows:
        return
    print(f"\n\"two candidates\" refusals with recorded evidence and the target among them: {len(rows)}")
    print(f"{'session':32} {'cid':4} {'best is target':>14} {'ratio':>6}")
    for c in rows:
        ev = np.asarray(c["evidence"], float)
        order = np.argsort(-ev)
        ratio = ev[order[0]] / max(ev[order[1]], 1e-12) if len(ev) > 1 else np.inf
        print(f"{c['session']:32} {c['cid']:4} {str(int(order[0]) == c['truth']):>14} {ratio:6.2f}")


def wrong_centres(paths: list[Path], cases: list[dict]) -> None:
    """Captures with a target whose entry's centre is more than 2 cm off, per capture and after
    the scenery cue at the shares in use (the images are not rendered in the sweep)."""
    wrong, n = [], 0
    for f in sorted(p for d in paths for p in Path(d).glob("*.json")):
        for cid, c in json.loads(f.read_text())["captures"].items():
            e = c["sonar"]
            n += c["target"]
            if c["target"] and e.get("center") is not None and \
                    np.linalg.norm(np.subtract(e["center"], c["truth"])) > 0.02:
                wrong.append((f.stem, cid))
    fixed = [(c["session"], c["cid"]) for c in cases
             if c["kind"] == "winner" and _settle(c, STATIC_SHARE, MOVING_SHARE) == "right"]
    made = [(c["session"], c["cid"]) for c in cases if _settle(c, STATIC_SHARE, MOVING_SHARE) == "wrong"]
    after = [w for w in wrong if w not in fixed] + made
    print(f"\nwrong centres (> 2 cm off) among {n} captures with a target: {len(wrong)} per capture "
          f"({', '.join(' '.join(w) for w in wrong) or '-'}); after the scenery cue: {len(after)}")
