"""One UDP endpoint serving one or more simulated vehicles (a shared radio link is one endpoint;
vehicles are told apart by system id). pymavlink is only the codec.

Connection URLs are written from the controller's side; the endpoint takes the other side:

* ``udpin://H:P`` - the controller listens there: the endpoint sends to it (from an ephemeral port)
* ``udp://H:P`` / ``udpout://H:P`` - the controller sends there: the endpoint binds H:P (P = 0: any)
* ``sim`` - bind a free loopback port; the controller uses ``udp://127.0.0.1:PORT``

Faults are applied here per vehicle: dropout (silent and deaf), packet loss in both directions
(per MAVLink message), latency (each direction). Malformed and truncated datagrams are counted
and dropped.
"""

from __future__ import annotations

import asyncio
import logging
import random
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any, cast
from urllib.parse import urlsplit

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from .faults import FaultBook
from .vehicle import Clock, SimVehicle

log = logging.getLogger(__name__)

MAX_DATAGRAM = 1200  # bytes of MAVLink messages packed into one datagram
MAX_PEERS = 16
GCS_TYPE = 6  # MAV_TYPE_GCS


class LinkError(ValueError):
    """A connection URL the simulated fleet cannot serve."""


@dataclass(frozen=True)
class LinkSpec:
    """Where an endpoint lives. ``mode`` is "bind" (we listen) or "send" (we send to ``host:port``)."""

    url: str  # as written in the config
    mode: str
    host: str
    port: int

    def controller_url(self, bound_port: int) -> str:
        """The URL the controller uses to reach this endpoint."""
        if self.url == "sim":
            return f"udp://{self.host}:{bound_port}"
        if self.mode == "bind":
            scheme = urlsplit(self.url).scheme
            return f"{scheme}://{self.host}:{bound_port}"
        return self.url


def parse_connection(url: str) -> LinkSpec:
    """Parse a controller-side connection URL (``sim``, ``udp://``, ``udpout://``, ``udpin://``)."""
    if url == "sim":
        return LinkSpec(url, "bind", "127.0.0.1", 0)
    parts = urlsplit(url)
    scheme = parts.scheme.lower()
    if scheme in ("tcp", "tcpin", "tcpout"):
        raise LinkError(f"connection {url!r}: the simulated fleet serves UDP only; "
                        "use udp://, udpin:// or sim")
    if scheme == "serial":
        raise LinkError(f"connection {url!r}: a serial port cannot be simulated; use udp://, udpin:// or sim")
    if scheme not in ("udp", "udpout", "udpin"):
        raise LinkError(f"connection {url!r}: unknown scheme; use sim, udp://HOST:PORT or udpin://HOST:PORT")
    try:
        port = parts.port
    except ValueError:
        port = None
    if port is None:
        raise LinkError(f"connection {url!r}: needs a port, e.g. {scheme}://127.0.0.1:14550")
    host = parts.hostname or ("127.0.0.1" if scheme == "udpin" else "0.0.0.0")
    if scheme == "udpin":
        if port == 0:
            raise LinkError(f"connection {url!r}: the controller's listening port cannot be 0")
        if host in ("0.0.0.0", "::"):
            host = "127.0.0.1"
        return LinkSpec(url, "send", host, port)
    return LinkSpec(url, "bind", host, port)


@dataclass
class LinkStats:
    rx_datagrams: int = 0
    rx_messages: int = 0
    rx_bad: int = 0  # malformed: bad prefix, CRC, unknown id, undecodable
    rx_truncated: int = 0  # datagrams ending inside a message
    rx_lost: int = 0  # messages dropped by simulated packet loss
    rx_deaf: int = 0  # messages not heard because the vehicle is in dropout
    tx_messages: int = 0
    tx_datagrams: int = 0
    tx_lost: int = 0
    tx_silent: int = 0  # messages not sent because the vehicle is in dropout
    tx_no_peer: int = 0  # nobody to send to yet (bind mode before the controller spoke)

    def as_dict(self) -> dict[str, int]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


def _new_parser() -> Any:
    p = mavlink2.MAVLink(None)
    p.robust_parsing = True
    return p


class UdpEndpoint(asyncio.DatagramProtocol):
    """asyncio UDP endpoint for the vehicles attached to it."""

    def __init__(self, spec: LinkSpec, clock: Clock, faults: FaultBook, seed: int, name: str = "") -> None:
        self.spec = spec
        self.clock = clock
        self.faults = faults
        self.rng = random.Random(f"{seed}:{spec.url}:{name}")  # packet loss: deterministic per seed
        self.vehicles: dict[int, SimVehicle] = {}
        self.stats = LinkStats()
        self.peers: dict[Any, float] = {}
        self.routes: dict[int, Any] = {}  # remote sysid -> address it was last heard from
        self._parsers: dict[Any, Any] = {}
        self._pending: dict[Any, list[bytes]] = {}
        self._flush_scheduled = False
        self._timers: set[asyncio.TimerHandle] = set()
        self.transport: asyncio.DatagramTransport | None = None
        self.bound_port = 0
        self._loop: asyncio.AbstractEventLoop | None = None

    # -- lifecycle -------------------------------------------------------------------------
    def attach(self, vehicle: SimVehicle) -> None:
        self.vehicles[vehicle.sysid] = vehicle
        vehicle.link = self

    async def open(self) -> None:
        loop = asyncio.get_running_loop()
        self._loop = loop
        spec = self.spec
        if spec.mode == "bind":
            local = (spec.host, spec.port)
        else:
            local = ("127.0.0.1" if spec.host.startswith("127.") else "0.0.0.0", 0)
            self.peers[(spec.host, spec.port)] = 0.0
        try:
            await loop.create_datagram_endpoint(lambda: self, local_addr=local)
        except OSError as exc:
            raise LinkError(f"connection {spec.url!r}: cannot open UDP {local[0]}:{local[1]} "
                            f"({exc.strerror}); choose another port or stop what uses it") from None
        assert self.transport is not None
        self.bound_port = self.transport.get_extra_info("sockname")[1]

    @property
    def url(self) -> str:
        return self.spec.controller_url(self.bound_port)

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        # asyncio hands a datagram protocol its DatagramTransport; typeshed declares the base class
        self.transport = cast(asyncio.DatagramTransport, transport)

    def connection_lost(self, exc: Exception | None) -> None:
        self.transport = None

    def error_received(self, exc: Exception) -> None:
        log.debug("%s: %s", self.spec.url, exc)  # e.g. ICMP port unreachable while nobody listens

    def close(self) -> None:
        for h in self._timers:
            h.cancel()
        self._timers.clear()
        self._pending.clear()
        if self.transport is not None:
            self.transport.close()
            self.transport = None

    # -- receive ---------------------------------------------------------------------------
    def datagram_received(self, data: bytes, addr: Any) -> None:
        st = self.stats
        st.rx_datagrams += 1
        if addr not in self.peers and len(self.peers) >= MAX_PEERS:
            del self.peers[min(self.peers, key=self.peers.__getitem__)]
        self.peers[addr] = self.clock.wall()
        parser = self._parsers.get(addr)
        if parser is None:
            parser = self._parsers[addr] = _new_parser()
        try:
            msgs = parser.parse_buffer(data) or []
        except Exception as exc:  # noqa: BLE001 - a datagram must never take the simulator down
            log.debug("%s: undecodable datagram from %s: %s", self.spec.url, addr, exc)
            st.rx_bad += 1
            self._parsers[addr] = _new_parser()
            return
        if parser.buf_len() > 0:  # a datagram is self-contained: a partial message is truncated
            st.rx_truncated += 1
            self._parsers[addr] = _new_parser()
        for msg in msgs:
            if msg.get_type() == "BAD_DATA":
                st.rx_bad += 1
                continue
            st.rx_messages += 1
            src = msg.get_srcSystem()
            if src in self.vehicles:
                continue  # our own traffic reflected back
            self.routes[src] = addr
            if msg.get_type() == "HEARTBEAT" and msg.type == GCS_TYPE:
                self._forward(msg, addr)
            target = getattr(msg, "target_system", 0)
            if target:
                v = self.vehicles.get(target)
                if v is not None:
                    self._deliver(v, msg, addr)
                else:
                    for v in self.vehicles.values():  # counted as ignored by each vehicle
                        v.ignored_other_target += 1
            else:
                for v in list(self.vehicles.values()):
                    self._deliver(v, msg, addr)

    def _forward(self, msg: Any, addr: Any) -> None:
        """Route a ground station's HEARTBEAT to the other ground stations heard on this link, as
        an autopilot's MAVLink routing does (so one controller sees that another is there)."""
        for peer in self.peers:
            if peer != addr:
                self._pending.setdefault(peer, []).append(bytes(msg.get_msgbuf()))
        if not self._flush_scheduled and self._loop is not None and len(self.peers) > 1:
            self._flush_scheduled = True
            self._loop.call_soon(self.flush)

    def _deliver(self, v: SimVehicle, msg: Any, addr: Any) -> None:
        t = self.clock.sim_time
        faults = self.faults
        if len(faults):
            if faults.dropped(v.id, t):
                self.stats.rx_deaf += 1
                return
            loss = faults.loss_rate(v.id, t)
            if loss > 0 and self.rng.random() < loss:
                self.stats.rx_lost += 1
                return
            delay = faults.latency(v.id, t)
            if delay > 0:
                self._later(delay, self._handle_safely, v, msg, addr)
                return
        self._handle_safely(v, msg, addr)

    def _handle_safely(self, v: SimVehicle, msg: Any, addr: Any) -> None:
        try:
            v.handle(msg, addr)
        except Exception:  # noqa: BLE001 - log, count and keep serving
            self.stats.rx_bad += 1
            log.exception("%s: error handling %s", v.id, msg.get_type())

    # -- send ------------------------------------------------------------------------------
    def send(self, vehicle: SimVehicle, data: bytes, addr: Any | None) -> None:
        """Queue one packed message from ``vehicle`` (to ``addr``, or to every peer)."""
        st = self.stats
        faults = self.faults
        if len(faults):
            t = self.clock.sim_time
            if faults.dropped(vehicle.id, t):
                st.tx_silent += 1
                return
            loss = faults.loss_rate(vehicle.id, t)
            if loss > 0 and self.rng.random() < loss:
                st.tx_lost += 1
                return
            delay = faults.latency(vehicle.id, t)
            if delay > 0:
                self._later(delay, self._queue, data, addr)
                return
        self._queue(data, addr)

    def _queue(self, data: bytes, addr: Any | None) -> None:
        if addr is None:
            if not self.peers:
                self.stats.tx_no_peer += 1
                return
            for peer in self.peers:
                self._pending.setdefault(peer, []).append(data)
        else:
            self._pending.setdefault(addr, []).append(data)
        self.stats.tx_messages += 1
        if not self._flush_scheduled and self._loop is not None:
            self._flush_scheduled = True
            self._loop.call_soon(self.flush)

    def flush(self) -> None:
        """Send the queued messages, several per datagram."""
        self._flush_scheduled = False
        pending, self._pending = self._pending, {}
        tr = self.transport
        if tr is None:
            return
        for addr, chunks in pending.items():
            buf = bytearray()
            for c in chunks:
                if buf and len(buf) + len(c) > MAX_DATAGRAM:
                    tr.sendto(bytes(buf), addr)
                    self.stats.tx_datagrams += 1
                    buf = bytearray()
                buf += c
            if buf:
                tr.sendto(bytes(buf), addr)
                self.stats.tx_datagrams += 1

    def _later(self, delay: float, fn: Callable[..., None], *args: Any) -> None:
        if self._loop is None:
            return
        handle: asyncio.TimerHandle

        def run() -> None:
            self._timers.discard(handle)
            fn(*args)

        handle = self._loop.call_later(delay, run)
        self._timers.add(handle)
