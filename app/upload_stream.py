"""Receive an upload from the browser straight to disk, refusing an over-size one at once.

viser 1.1.1 keeps every part of an upload in memory and joins them at the end (twice the
file's size) before the app sees it. The first message of an upload declares its size,
so for the workbench's upload button this module replaces viser's two handlers: an
upload declared larger than the limit is refused before any part arrives (its parts are
then dropped as they come), and the parts of an accepted one are written to a file in
the uploads folder as they arrive. Uploads to any other button still go to viser.
"""

from __future__ import annotations

import logging
import threading
from pathlib import Path
from typing import Callable

from viser import _messages as vm

from app.uploads import UploadStore, oversize_problem

log = logging.getLogger("sonarcal.app")


class _Transfer:
    def __init__(self, client_id, name: str, path: Path, parts: int, size: int):
        self.client_id, self.name, self.path = client_id, name, path
        self.parts, self.size = parts, size
        self.next_index, self.received = 0, 0
        self.pending: dict[int, bytes] = {}  # parts that arrived early (bounded by the declared size)
        self.file = open(path, "wb")


class UploadReceiver:
    """Streams uploads of one button to ``store``; calls ``on_file(client_id, name, path)``
    in a worker thread when one is complete, ``on_refuse(client_id, name, problem)`` when not.
    The callee owns (and deletes) the file it is given."""

    def __init__(self, server, button, store: UploadStore, max_bytes: int,
                 on_file: Callable, on_refuse: Callable):
        self.server, self.store, self.max_bytes = server, store, max_bytes
        self.on_file, self.on_refuse = on_file, on_refuse
        self.uuid = button._impl.uuid
        self.transfers: dict[str, _Transfer] = {}
        self.refused: set[str] = set()
        self.lock = threading.Lock()
        ws = server._websock_server
        self._viser_start = server.gui._handle_file_transfer_start
        self._viser_part = server.gui._handle_file_transfer_part
        ws.unregister_handler(vm.FileTransferStartUpload, self._viser_start)
        ws.unregister_handler(vm.FileTransferPart, self._viser_part)
        ws.register_handler(vm.FileTransferStartUpload, self._start)
        ws.register_handler(vm.FileTransferPart, self._part)
        server.on_client_disconnect(self._disconnected)

    def _ack(self, message, done: int, total: int) -> None:
        self.server._websock_server.queue_message(vm.FileTransferPartAck(
            source_component_uuid=message.source_component_uuid, transfer_uuid=message.transfer_uuid,
            transferred_bytes=done, total_bytes=total))

    def _start(self, client_id, message) -> None:
        if message.source_component_uuid != self.uuid:
            return self._viser_start(client_id, message)
        name = str(message.filename)[:200]
        size, parts = int(message.size_bytes), int(message.part_count)
        if size > self.max_bytes or size < 0 or parts < 0 or parts > size // 1024 + 2:
            with self.lock:
                self.refused.add(message.transfer_uuid)
            self._ack(message, size, size)  # closes the page's progress notice
            problem = oversize_problem(size, self.max_bytes) if size > self.max_bytes else "upload declares a bad size"
            self.on_refuse(client_id, name, problem)
            return None
        t = _Transfer(client_id, name, self.store.incoming_file(), parts, size)
        with self.lock:
            self.transfers[message.transfer_uuid] = t
        if parts == 0:
            self._finish(message.transfer_uuid)
        return None

    def _part(self, client_id, message) -> None:
        if message.source_component_uuid != self.uuid:
            return self._viser_part(client_id, message)
        with self.lock:
            t = self.transfers.get(message.transfer_uuid)
            if t is None or t.client_id != client_id:
                return None  # refused, finished or unknown: dropped, never held
            idx, data = int(message.part_index), bytes(message.content)
            if not (t.next_index <= idx < t.parts) or idx in t.pending or t.received + len(data) > t.size:
                self._drop(message.transfer_uuid, "upload parts do not match the declared size")
                return None
            t.received += len(data)
            t.pending[idx] = data
            while t.next_index in t.pending:
                t.file.write(t.pending.pop(t.next_index))
                t.next_index += 1
            done = t.next_index == t.parts
        self._ack(message, t.received, t.size)
        if done:
            self._finish(message.transfer_uuid)
        return None

    def _finish(self, transfer_uuid: str) -> None:
        with self.lock:
            t = self.transfers.pop(transfer_uuid, None)
        if t is None:
            return
        t.file.close()
        if t.received != t.size:
            t.path.unlink(missing_ok=True)
            self.on_refuse(t.client_id, t.name, "upload parts do not match the declared size")
            return
        threading.Thread(target=self.on_file, args=(t.client_id, t.name, t.path), daemon=True,
                         name="sonarcal-upload").start()

    def _drop(self, transfer_uuid: str, problem: str | None) -> None:
        """Forget a transfer and delete its partial file (call with the lock held)."""
        t = self.transfers.pop(transfer_uuid, None)
        if t is None:
            return
        t.file.close()
        t.path.unlink(missing_ok=True)
        if problem:
            threading.Thread(target=self.on_refuse, args=(t.client_id, t.name, problem), daemon=True).start()

    def _disconnected(self, client) -> None:
        with self.lock:
            for tid in [k for k, t in self.transfers.items() if t.client_id == client.client_id]:
                self._drop(tid, None)
