"""MAVLink telemetry logs (``.tlog``) in pymavlink's format: each message is preceded by its
receive/send time as an 8-byte big-endian unsigned integer of microseconds since the Unix epoch.
Readable by ``pymavlink.mavutil.mavlink_connection(path)`` and ``mavlogdump.py``.

``TlogWriter`` is a :data:`fleetctl.link.Tap`: ``link.add_tap(writer)`` (or ``fleet.add_tap``)
logs both directions. Records are buffered in memory and written by a worker thread every
``flush_interval`` seconds, so the event loop never waits on the disk.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import struct
import threading
from pathlib import Path

log = logging.getLogger(__name__)

_TS = struct.Struct(">Q")


def tlog_record(timestamp: float, data: bytes) -> bytes:
    """One tlog record: ``timestamp`` (Unix seconds) and the raw MAVLink message bytes."""
    return _TS.pack(int(round(timestamp * 1e6))) + data


class TlogWriter:
    """Append MAVLink messages to a ``.tlog`` file.

    Use as a tap: ``writer(direction, unix_time, raw_bytes)``. In a running event loop call
    ``writer.start()`` to flush in the background and ``await writer.aclose()`` at the end;
    without a loop, ``writer.flush()`` / ``writer.close()`` write synchronously.
    """

    def __init__(self, path: str | Path, flush_interval: float = 0.5) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.flush_interval = flush_interval
        self.records = 0
        self._buf: list[bytes] = []
        self._lock = threading.Lock()  # the file is written from worker threads, one at a time
        self._file = self.path.open("ab")
        self._task: asyncio.Task[None] | None = None
        self._closed = False

    def __call__(self, direction: str, timestamp: float, data: bytes) -> None:
        self.write(timestamp, data)

    def write(self, timestamp: float, data: bytes) -> None:
        """Queue one message (cheap; no I/O)."""
        if self._closed:
            return
        self._buf.append(tlog_record(timestamp, data))
        self.records += 1

    def flush(self) -> None:
        """Write what is queued (blocking; called from a worker thread by the background task)."""
        buf, self._buf = self._buf, []
        if not buf:
            return
        with self._lock:
            self._file.write(b"".join(buf))
            self._file.flush()

    def start(self) -> None:
        """Flush every ``flush_interval`` s in the background (needs a running loop)."""
        if self._task is None:
            self._task = asyncio.get_running_loop().create_task(self._flusher(), name=f"tlog {self.path}")

    async def _flusher(self) -> None:
        while True:
            await asyncio.sleep(self.flush_interval)
            await asyncio.to_thread(self.flush)

    async def aclose(self) -> None:
        """Stop the background flush, write the rest and close the file."""
        task, self._task = self._task, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
        await asyncio.to_thread(self.close)

    def close(self) -> None:
        if self._closed:
            return
        self.flush()
        self._closed = True
        with self._lock:
            self._file.close()
        log.info("tlog %s: %d messages", self.path, self.records)


__all__ = ["TlogWriter", "tlog_record"]
