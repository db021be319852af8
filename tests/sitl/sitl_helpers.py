"""Helpers for the sitl tests: fleet configs and a small asyncio ground station that speaks
MAVLink 2 over UDP (real sockets on 127.0.0.1)."""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable
from typing import Any
from urllib.parse import urlsplit

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl import Fault, FleetConfig, VehicleSpec

ORIGIN = (47.397742, 8.545594, 488.0)
GCS_SYSID = 255
GCS_COMPID = 190


def make_config(
    n_rovers: int = 2,
    *,
    autopilot: str = "px4",
    speedup: float = 20.0,
    carrier_connection: str = "sim",
    rover_connections: list[str | None] | None = None,
    rover_accel: float | None = None,
    rover_speed: float = 5.0,
    endurance_range: float | None = 200.0,
    carrier_accel: float | None = 5.0,
    turn_rate: float | None = None,
    faults: list[Fault] | None = None,
    seed: int = 0,
) -> FleetConfig:
    rovers = [
        VehicleSpec(
            id=f"r{k + 1}", sysid=11 + k, role="rover", max_speed=rover_speed, accel=rover_accel,
            endurance_range=endurance_range,
            connection=None if rover_connections is None else rover_connections[k],
        )
        for k in range(n_rovers)
    ]
    carrier = VehicleSpec(id="carrier", sysid=1, role="carrier", max_speed=10.0, accel=carrier_accel,
                          turn_rate=turn_rate, connection=carrier_connection, position=(0.0, 0.0, 0.0),
                          frame="ground")
    return FleetConfig(origin=ORIGIN, carrier=carrier, rovers=rovers, speedup=speedup, seed=seed,
                       faults=faults or [], autopilot=autopilot)


def url_addr(url: str) -> tuple[str, int]:
    parts = urlsplit(url)
    assert parts.hostname is not None and parts.port is not None
    return parts.hostname, parts.port


class Gcs(asyncio.DatagramProtocol):
    """A minimal ground station for tests: sends to one UDP address and records everything."""

    def __init__(self, sysid: int = GCS_SYSID, compid: int = GCS_COMPID) -> None:
        self.mav = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.parser = mavlink2.MAVLink(None)
        self.parser.robust_parsing = True
        self.received: list[Any] = []
        self._new = asyncio.Event()
        self.transport: asyncio.DatagramTransport | None = None
        self.remote: tuple[str, int] | None = None
        self.datagrams = 0

    # asyncio protocol
    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport  # type: ignore[assignment]

    def datagram_received(self, data: bytes, addr: Any) -> None:
        self.datagrams += 1
        if self.remote is None:
            self.remote = addr
        for m in self.parser.parse_buffer(data) or []:
            if m.get_type() != "BAD_DATA":
                self.received.append(m)
        self._new.set()

    # helpers
    def send(self, msg: Any) -> None:
        assert self.transport is not None and self.remote is not None
        data = msg.pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) & 0xFF
        self.transport.sendto(data, self.remote)

    def send_raw(self, data: bytes) -> None:
        assert self.transport is not None and self.remote is not None
        self.transport.sendto(data, self.remote)

    def mark(self) -> int:
        return len(self.received)

    async def recv(
        self, mtype: str, *, sysid: int | None = None, since: int | None = None,
        where: Callable[[Any], bool] | None = None, timeout: float = 3.0,
    ) -> Any:
        """The first message of ``mtype`` (from ``sysid``) received after index ``since``."""
        idx = 0 if since is None else since
        async with asyncio.timeout(timeout):
            while True:
                while idx < len(self.received):
                    m = self.received[idx]
                    idx += 1
                    if m.get_type() == mtype and (sysid is None or m.get_srcSystem() == sysid) and (
                            where is None or where(m)):
                        return m
                self._new.clear()
                await self._new.wait()

    async def none(self, mtype: str, *, sysid: int | None = None, since: int, wait: float,
                   where: Callable[[Any], bool] | None = None) -> None:
        """Assert that no such message arrives within ``wait`` seconds."""
        try:
            m = await self.recv(mtype, sysid=sysid, since=since, where=where, timeout=wait)
        except TimeoutError:
            return
        raise AssertionError(f"unexpected {m}")

    async def command(self, sysid: int, command: int, *params: float, timeout: float = 3.0) -> Any:
        p = list(params) + [0.0] * (7 - len(params))
        since = self.mark()
        self.send(self.mav.command_long_encode(sysid, 1, command, 0, *p))
        return await self.recv("COMMAND_ACK", sysid=sysid, since=since, timeout=timeout,
                               where=lambda m: m.command == command)

    async def command_int(self, sysid: int, command: int, frame: int,
                          params: tuple[float, float, float, float], lat: float, lon: float, alt: float,
                          timeout: float = 3.0) -> Any:
        since = self.mark()
        self.send(self.mav.command_int_encode(sysid, 1, frame, command, 0, 0, *params,
                                              int(round(lat * 1e7)), int(round(lon * 1e7)), alt))
        return await self.recv("COMMAND_ACK", sysid=sysid, since=since, timeout=timeout,
                               where=lambda m: m.command == command)

    async def upload(self, sysid: int, items: list[tuple], timeout: float = 5.0) -> int:
        """Upload (frame, command, p1..p4, lat, lon, alt) items; returns the MISSION_ACK type."""
        since = self.mark()
        self.send(self.mav.mission_count_encode(sysid, 1, len(items), 0))
        async with asyncio.timeout(timeout):
            while True:
                m = await self._next_mission_msg(sysid, since)
                since = self.received.index(m) + 1
                if m.get_type() == "MISSION_ACK":
                    return m.type
                frame, cmd, p1, p2, p3, p4, lat, lon, alt = items[m.seq]
                self.send(self.mav.mission_item_int_encode(
                    sysid, 1, m.seq, frame, cmd, 0, 1, p1, p2, p3, p4,
                    int(round(lat * 1e7)), int(round(lon * 1e7)), alt, 0))

    async def _next_mission_msg(self, sysid: int, since: int) -> Any:
        idx = since
        while True:
            while idx < len(self.received):
                m = self.received[idx]
                idx += 1
                if m.get_srcSystem() == sysid and m.get_type() in ("MISSION_REQUEST_INT", "MISSION_ACK"):
                    return m
            self._new.clear()
            await self._new.wait()

    async def download(self, sysid: int, timeout: float = 5.0) -> list[Any]:
        since = self.mark()
        self.send(self.mav.mission_request_list_encode(sysid, 1, 0))
        count = await self.recv("MISSION_COUNT", sysid=sysid, since=since, timeout=timeout)
        items = []
        for seq in range(count.count):
            since = self.mark()
            self.send(self.mav.mission_request_int_encode(sysid, 1, seq, 0))
            items.append(await self.recv("MISSION_ITEM_INT", sysid=sysid, since=since, timeout=timeout,
                                         where=lambda m, s=seq: m.seq == s))
        self.send(self.mav.mission_ack_encode(sysid, 1, mavlink2.MAV_MISSION_ACCEPTED, 0))
        return items

    def close(self) -> None:
        if self.transport is not None:
            self.transport.close()


async def open_gcs(url: str, sysid: int = GCS_SYSID) -> Gcs:
    """A GCS talking to a fleet endpoint given by its controller-side ``udp://`` URL."""
    loop = asyncio.get_running_loop()
    gcs = Gcs(sysid)
    await loop.create_datagram_endpoint(lambda: gcs, local_addr=("127.0.0.1", 0))
    gcs.remote = url_addr(url)
    gcs.send(gcs.mav.heartbeat_encode(mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, 0))
    return gcs


def enu_to_latlon(x: float, y: float) -> tuple[float, float]:
    import pymap3d

    lat, lon, _ = pymap3d.enu2geodetic(x, y, 0.0, *ORIGIN)
    return float(lat), float(lon)


def near(a: tuple[float, ...], b: tuple[float, ...], tol: float = 0.05) -> bool:
    return math.dist(a, b) <= tol
