"""MAVLink telemetry logs (``.tlog``) in pymavlink's format: each message is preceded by its
receive/send time as an 8-byte big-endian unsigned integer of microseconds since the Unix epoch.
Readable by ``pymavlink.mavutil.mavlink_connection(path)`` and ``mavlogdump.py``.

``TlogWriter`` is a :data:`fleetctl.mavlink.link.Tap`: ``link.add_tap(writer)`` (or ``fleet.add_tap``)
logs both directions. Records are buffered in memory and written by a worker thread every
``flush_interval`` seconds, so the event loop never waits on the disk. :func:`read_telemetry` reads
the autopilots' positions and batteries back (``fleetctl replay``).
"""

from __future__ import annotations

import contextlib
import logging
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

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


class TlogError(Exception):
    """A ``.tlog`` that pymavlink cannot open."""


@dataclass(frozen=True)
class TlogPosition:
    """A GLOBAL_POSITION_INT of an autopilot (component 1) at Unix time ``t``: WGS84 degrees, metres
    above mean sea level and above home, horizontal ground speed in m/s."""

    t: float
    sysid: int
    lat: float
    lon: float
    alt: float
    relative_alt: float
    speed: float


@dataclass(frozen=True)
class TlogBattery:
    """A BATTERY_STATUS of an autopilot at Unix time ``t``: remaining percent, None when unknown."""

    t: float
    sysid: int
    pct: float | None


def read_telemetry(path: str | Path) -> Iterator[TlogPosition | TlogBattery]:
    """The autopilots' positions and batteries in a ``.tlog``, in the order logged."""
    from pymavlink import mavutil

    try:
        mlog = mavutil.mavlink_connection(str(path))
    except Exception as exc:  # noqa: BLE001 - pymavlink raises many kinds
        raise TlogError(f"{path}: cannot read the MAVLink log: {exc}") from None
    try:
        while (msg := mlog.recv_match(type=["GLOBAL_POSITION_INT", "BATTERY_STATUS"])) is not None:
            if msg.get_srcComponent() == 1:
                yield _telemetry(msg)
    finally:
        with contextlib.suppress(Exception):
            mlog.close()


def _telemetry(msg: Any) -> TlogPosition | TlogBattery:
    t, sysid = float(getattr(msg, "_timestamp", 0.0)), msg.get_srcSystem()
    if msg.get_type() == "BATTERY_STATUS":
        rem = msg.battery_remaining
        return TlogBattery(t, sysid, float(rem) if rem >= 0 else None)
    speed = (msg.vx * msg.vx + msg.vy * msg.vy) ** 0.5 / 100.0
    return TlogPosition(t, sysid, msg.lat / 1e7, msg.lon / 1e7, msg.alt / 1000.0, msg.relative_alt / 1000.0,
                        speed)
