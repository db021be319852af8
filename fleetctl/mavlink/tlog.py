"""MAVLink telemetry logs (``.tlog``) in pymavlink's format: each message is preceded by its
receive/send time as an 8-byte big-endian unsigned integer of microseconds since the Unix epoch.
Readable by ``pymavlink.mavutil.mavlink_connection(path)`` and ``mavlogdump.py``.

``TlogWriter`` is a :data:`fleetctl.mavlink.link.Tap`: ``link.add_tap(writer)`` (or ``fleet.add_tap``)
logs both directions. Records are buffered in memory and written by a worker thread every
``flush_interval`` seconds, so the event loop never waits on the disk.
"""

from __future__ import annotations

import logging
import struct
from pathlib import Path

from fleetctl.background_file import BackgroundFile

log = logging.getLogger(__name__)

_TS = struct.Struct(">Q")


def tlog_record(timestamp: float, data: bytes) -> bytes:
    """One tlog record: ``timestamp`` (Unix seconds) and the raw MAVLink message bytes."""
    return _TS.pack(int(round(timestamp * 1e6))) + data


class TlogWriter(BackgroundFile[bytes]):
    """Append MAVLink messages to a ``.tlog`` file.

    Use as a tap: ``writer(direction, unix_time, raw_bytes)``. In a running event loop call
    ``writer.start()`` to flush in the background and ``await writer.aclose()`` at the end;
    without a loop, ``writer.flush()`` / ``writer.close()`` write synchronously.
    """

    def __init__(self, path: str | Path, flush_interval: float = 0.5) -> None:
        super().__init__(path, binary=True, flush_interval=flush_interval)

    def __call__(self, direction: str, timestamp: float, data: bytes) -> None:
        self.write(timestamp, data)

    def write(self, timestamp: float, data: bytes) -> None:
        """Queue one message (cheap; no I/O)."""
        self.queue(tlog_record(timestamp, data))

    def close(self) -> None:
        if not self._closed:
            super().close()
            log.info("tlog %s: %d messages", self.path, self.records)


__all__ = ["TlogWriter", "tlog_record"]
