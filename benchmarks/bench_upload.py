"""Uploads (issue 14): server memory for an over-size upload and for a large accepted one.

    .venv/bin/python benchmarks/bench_upload.py [--mb 150]

A workbench runs in a child process; this process uploads through a real websocket, with
the token, the way viser's page does (512 kB parts). The child's peak RSS (VmHWM from
/proc/PID/status, reset before each case through /proc/PID/clear_refs) minus its RSS
before the case is the memory the upload cost the server. Before issue 14 viser held an
upload whole in memory and then joined its parts (twice its size: +629 MB for an over-size
upload). Target: an over-size upload refused from its first message (nothing stored, no
growth), an accepted one streamed to disk (growth far below its size).
"""

from __future__ import annotations

import argparse
import io
import json
import os
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

CHILD = r"""
import json, sys, time
sys.path.insert(0, sys.argv[2])
from conftest import build_session
from pathlib import Path
from app.server import Workbench
wb = Workbench(build_session(Path(sys.argv[1]), n_captures=2), port=0, uploads_dir=Path(sys.argv[1]) / "up")
wb.wait_idle(60)
print(json.dumps({"port": wb.port, "token": wb.token, "uuid": wb.session_panel.upload._impl.uuid}), flush=True)
while True:
    line = sys.stdin.readline()
    if not line:
        break
    print(json.dumps({"session": wb.state.session.name, "refused": sorted(wb.session_panel.receiver.refused)}), flush=True)
wb.stop()
"""


def read_json(child) -> dict:
    """The child's next JSON line (viser prints its own banner on the same stdout)."""
    while True:
        line = child.stdout.readline()
        if not line:
            raise RuntimeError("the workbench child stopped")
        if line.startswith("{"):
            return json.loads(line)


def status_kb(pid: int, key: str) -> int:
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1])
    return -1


def upload(ws, uuid: str, tid: str, data_len: int, declared: int, payload: bytes | None = None) -> None:
    import msgspec

    part = 512 * 1024
    n = (declared + part - 1) // part
    send = lambda **m: ws.send(msgspec.msgpack.encode(m))  # noqa: E731
    send(type="FileTransferStartUpload", source_component_uuid=uuid, transfer_uuid=tid, filename=f"{tid}.zip",
         mime_type="application/zip", part_count=n, size_bytes=declared)
    chunk = bytes(part)
    for i in range((data_len + part - 1) // part):
        body = payload[i * part:(i + 1) * part] if payload is not None else chunk
        send(type="FileTransferPart", source_component_uuid=uuid, transfer_uuid=tid, part_index=i, content=body)


def session_zip(tmp: Path, mb: int) -> bytes:
    from conftest import build_session

    src = build_session(tmp / "src", n_captures=2)
    manifest = src / "session.yaml"
    manifest.write_text(manifest.read_text().replace("name: test-session", "name: uploaded"))
    (src / "padding.bin").write_bytes(os.urandom(mb * 10**6))  # incompressible: the zip is about mb MB
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_STORED) as zf:
        for p in src.rglob("*"):
            if p.is_file():
                zf.write(p, "s/" + str(p.relative_to(src)))
    return buf.getvalue()


def main() -> int:
    import viser
    from websockets.sync.client import connect

    ap = argparse.ArgumentParser()
    ap.add_argument("--mb", type=int, default=150)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
        child = subprocess.Popen([sys.executable, "-c", CHILD, str(tmp / "wb"), str(ROOT / "tests")], env=env,
                                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        info = read_json(child)
        ws = connect(f"ws://127.0.0.1:{info['port']}/?token={info['token']}",
                     subprotocols=[f"viser-v{viser.__version__}"], max_size=None, open_timeout=30)
        payload = session_zip(tmp, args.mb)
        rows = []
        cases = [("over-size: declares 1 GB, sends 100 MB", 100 * 10**6, 10**9, None),
                 (f"accepted: {len(payload) / 1e6:.0f} MB session zip", len(payload), len(payload), payload)]
        for name, n_bytes, declared, data in cases:
            time.sleep(1.0)
            with open(f"/proc/{child.pid}/clear_refs", "w") as f:
                f.write("5")
            base = status_kb(child.pid, "VmRSS")
            t0 = time.monotonic()
            upload(ws, info["uuid"], name.split(":")[0], n_bytes, declared, data)
            deadline = time.monotonic() + 120
            while True:
                child.stdin.write("?\n")
                child.stdin.flush()
                state = read_json(child)
                done = state["session"] == "uploaded" if data is not None else "over-size" in state["refused"]
                if done or time.monotonic() > deadline:
                    break
                time.sleep(0.5)
            secs = time.monotonic() - t0
            time.sleep(3.0)  # parts still in flight are received (and dropped or written) before the peak is read
            growth = (status_kb(child.pid, "VmHWM") - base) / 1024
            rows.append((name, n_bytes / 1e6, growth, secs, state))
        ws.close()
        child.stdin.close()
        child.wait(timeout=60)
    print("| upload | bytes sent (MB) | server peak growth (MB) | s | outcome |\n|---|---|---|---|---|")
    for name, sent, growth, secs, state in rows:
        if name.startswith("over"):
            outcome = "refused from its first message" if "over-size" in state["refused"] else "NOT refused"
        else:
            outcome = "streamed, unpacked, opened" if state["session"] == "uploaded" else "NOT opened"
        print(f"| {name} | {sent:.0f} | {growth:.0f} | {secs:.1f} | {outcome} |")
    print(f"\nload average {open('/proc/loadavg').read().split()[:3]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
