"""Durable undo and redo from the change records kept in ``detections.yaml``.

Every operator change appends one record to the ``history`` list of each entry it touches::

    {time, action, status, center, client, change: 7, kind: do, before: {...}}

``change`` numbers a change across the whole file (all entries it touched share it), ``kind``
is ``do``, ``undo`` or ``redo`` (``of`` then names the change undone or redone) and
``before`` is the entry as it was just before (without its history; ``null`` when there
was none). Replaying the records in change order gives the undo and redo stacks, so undo
and redo survive reloads and restarts and are the same for every client and process
that opens the session. Records without ``change`` (older files) are kept but not undoable.
"""

from __future__ import annotations

import dataclasses


@dataclasses.dataclass
class ChangeInfo:
    """One change as the records tell it: id, action, client, kind, and the entries it touched."""

    id: int
    action: str
    client: str
    kind: str = "do"
    of: int | None = None
    items: list = dataclasses.field(default_factory=list)  # [(capture_id, sensor, record)]


def content(entry: dict | None) -> dict | None:
    """An entry without its change records."""
    return None if entry is None else {k: v for k, v in entry.items() if k != "history"}


def _records(detections: dict):
    for cid, sensors in detections.items():
        for sensor, e in (sensors or {}).items():
            for rec in (e or {}).get("history") or []:
                if isinstance(rec, dict) and isinstance(rec.get("change"), int):
                    yield cid, sensor, rec


def changes(detections: dict) -> dict[int, ChangeInfo]:
    """{change id: ChangeInfo} of every numbered record in ``detections``."""
    out: dict[int, ChangeInfo] = {}
    for cid, sensor, rec in _records(detections):
        ch = out.get(rec["change"])
        if ch is None:
            ch = out[rec["change"]] = ChangeInfo(rec["change"], str(rec.get("action", "")), str(rec.get("client", "")),
                                                 str(rec.get("kind", "do")), rec.get("of"))
        ch.items.append((cid, sensor, rec))
    return out


def next_change_id(detections: dict) -> int:
    return max(changes(detections), default=0) + 1


def stacks(detections: dict) -> tuple[list[ChangeInfo], list[ChangeInfo]]:
    """(done, undone): what Undo and Redo would take next is the last of each."""
    chs = changes(detections)
    done: list[int] = []
    undone: list[int] = []
    for cid in sorted(chs):
        ch = chs[cid]
        if ch.kind == "do":
            done.append(cid)
            undone.clear()  # a new change forgets what was undone before it
        elif ch.kind == "undo" and ch.of in done:
            done.remove(ch.of)
            undone.append(ch.of)
        elif ch.kind == "redo" and ch.of in undone:
            undone.remove(ch.of)
            done.append(ch.of)
    return [chs[i] for i in done], [chs[i] for i in undone]


def last_record(entry: dict | None) -> dict | None:
    hist = (entry or {}).get("history") or []
    return hist[-1] if hist and isinstance(hist[-1], dict) else None


def step_record(entry: dict | None, change_id: int, kind: str) -> tuple[dict | None, dict | None]:
    """For undoing (``kind="undo"``) or redoing change ``change_id`` on one entry:
    (the record that last applied or undid it, the entry's status and centre right after it).

    Undo looks for the change itself or its latest redo; redo for its latest undo. The
    content after a record is the next record's ``before`` (the records form a chain), or
    what the record itself states for the last record. Comparing that with the entry as it is
    tells whether it was changed since (by a later change or by hand).
    """
    hist = [r for r in (entry or {}).get("history") or [] if isinstance(r, dict)]
    for i in range(len(hist) - 1, -1, -1):
        r = hist[i]
        mine = r.get("change") == change_id and r.get("kind", "do") == "do" if kind == "undo" else False
        mine = mine or (r.get("of") == change_id and r.get("kind") == ("redo" if kind == "undo" else "undo"))
        if mine:
            after = hist[i + 1].get("before") if i + 1 < len(hist) else r
            return r, {"status": (after or {}).get("status"), "center": (after or {}).get("center")}
    return None, None
