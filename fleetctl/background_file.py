"""An append-only file written by a worker thread, so the event loop never waits on the disk.

Callers queue records with :meth:`BackgroundFile.queue` (no I/O); ``start()`` flushes every
``flush_interval`` seconds from a background task; ``await aclose()`` writes the rest. Without a
loop, ``flush()`` / ``close()`` write synchronously. Used by the journal and the ``.tlog``.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
from pathlib import Path
from typing import Generic, TypeVar

T = TypeVar("T", str, bytes)


class BackgroundFile(Generic[T]):
    def __init__(self, path: str | Path, *, binary: bool, flush_interval: float = 0.5) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.flush_interval = flush_interval
        self.records = 0
        self._buf: list[T] = []
        self._sep: str | bytes = b"" if binary else "\n"
        self._lock = threading.Lock()  # the file is written from worker threads, one at a time
        self._file = self.path.open("ab") if binary else self.path.open("a", encoding="utf-8")
        self._task: asyncio.Task[None] | None = None
        self._closed = False

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
        data = self._sep.join(buf) + ("\n" if self._sep == "\n" else b"")  # type: ignore[operator]
        with self._lock:
            if not self._file.closed:
                self._file.write(data)
                self._file.flush()

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
