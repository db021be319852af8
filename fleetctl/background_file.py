"""An append-only file written by a worker thread, so the event loop never waits on the disk.

Callers queue records with :meth:`BackgroundFile.queue` (no I/O); ``start()`` flushes every
``flush_interval`` seconds from a background task; ``await aclose()`` writes the rest. Without a
loop, ``flush()`` / ``close()`` write synchronously. Used by the journal and the ``.tlog``.

``await sync()`` is the write-ahead step: it returns once every record queued before the call is
written *and* fsynced (from a worker thread; concurrent callers share one fsync). Each flush is
one ``os.write`` of whole records on an unbuffered file, so a process killed at any moment
leaves only whole lines behind.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import threading
from pathlib import Path
from typing import Generic, TypeVar

from fleetctl.aio import cancel_and_wait

T = TypeVar("T", str, bytes)


class BackgroundFile(Generic[T]):
    def __init__(self, path: str | Path, *, binary: bool, flush_interval: float = 0.5) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.flush_interval = flush_interval
        self.records = 0
        self._buf: list[T] = []
        self._binary = binary
        self._lock = threading.Lock()  # the file is written from worker threads, one at a time
        self._file = self.path.open("ab", buffering=0)
        self._task: asyncio.Task[None] | None = None
        self._closed = False
        self._synced = 0  # records known to be on disk (fsynced)
        self._sync_lock: asyncio.Lock | None = None

    def queue(self, record: T) -> None:
        """Queue one record (cheap; no I/O). Text records are written one per line."""
        if self._closed:
            return
        self._buf.append(record)
        self.records += 1

    def flush(self) -> None:
        """Write what is queued (blocking; the background task calls it from a worker thread)."""
        buf, self._buf = self._buf, []
        if not buf:
            return
        if self._binary:
            data = b"".join(buf)  # type: ignore[arg-type]
        else:
            data = ("\n".join(buf) + "\n").encode("utf-8")  # type: ignore[arg-type]
        with self._lock:
            if not self._file.closed:
                view = memoryview(data)
                while view:  # one write(2) for a regular file; loop only on a short write
                    view = view[os.write(self._file.fileno(), view):]

    def _flush_and_fsync(self) -> None:
        self.flush()
        with self._lock:
            if not self._file.closed:
                os.fsync(self._file.fileno())

    async def sync(self) -> None:
        """Return once every record queued so far is on disk (written and fsynced)."""
        if self._closed:
            return
        target = self.records
        if self._sync_lock is None:
            self._sync_lock = asyncio.Lock()
        async with self._sync_lock:
            if self._synced >= target or self._closed:
                return
            upto = self.records
            await asyncio.to_thread(self._flush_and_fsync)
            self._synced = max(self._synced, upto)

    def start(self) -> None:
        """Flush every ``flush_interval`` s in the background (needs a running loop)."""
        if self._task is None:
            self._task = asyncio.get_running_loop().create_task(self._flusher(), name=f"flush {self.path}")

    async def _flusher(self) -> None:
        while True:
            await asyncio.sleep(self.flush_interval)
            await asyncio.to_thread(self.flush)

    async def aclose(self) -> None:
        """Stop the background flush, write the rest and close the file."""
        task, self._task = self._task, None
        await cancel_and_wait(task)
        await asyncio.to_thread(self.close)

    def close(self) -> None:
        if self._closed:
            return
        self.flush()
        self._closed = True
        with self._lock:
            with contextlib.suppress(OSError):
                os.fsync(self._file.fileno())
            self._file.close()
