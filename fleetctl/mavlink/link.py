"""Async MAVLink 2 transport: one :class:`Link` per connection URL, hosting any number of vehicles.

pymavlink is used only as the codec (``pymavlink.dialects.v20.ardupilotmega``); sockets, timers
and retries are asyncio. Nothing here blocks the event loop.

Connection URLs are written from the controller's side (docs/mavlink.md):

* ``udpin://HOST:PORT`` - listen there; a reply goes to the address its system id was last heard
  from, a broadcast (heartbeat) to every address heard from.
* ``udp://HOST:PORT`` (alias ``udpout://``) - send to a vehicle listening there and receive on
  the same socket.
* ``tcp://HOST:PORT`` - connect (reconnects after a drop while the link is open).
* ``serial:///dev/ttyX?baud=57600`` - needs the optional ``pyserial-asyncio`` package.

Layers, bottom up, a module each:

1. the URL (:mod:`fleetctl.mavlink.address`), the transport and one parser per remote address
   (here); incoming messages are routed by source system id (``Link.subscribe``) and offered to
   the registered expectations;
2. single request/response (:mod:`fleetctl.mavlink.expectations`): :meth:`Link.expect` (one
   future) and :meth:`Link.collect` (an inbox for a whole exchange) are registered *before* the
   request is sent;
3. the protocols with their retries: commands (:mod:`fleetctl.mavlink.command_protocol`, behind
   :meth:`Link.command`) and missions (:mod:`fleetctl.mavlink.mission_protocol`, behind
   :meth:`Link.upload_mission`, :meth:`Link.download_mission`, :meth:`Link.clear_mission`), which
   see the link only as a :class:`fleetctl.mavlink.channel.Channel`;
   signing (:mod:`fleetctl.mavlink.signing`); the values they carry
   (:mod:`fleetctl.mavlink.messages`) and the errors (:mod:`fleetctl.mavlink.errors`).

Every message in and out can be observed with :meth:`Link.add_tap` (``callback(direction,
unix_time, raw_bytes)``, direction ``"in"`` or ``"out"``), e.g. by :class:`fleetctl.mavlink.tlog.TlogWriter`.

Safety (docs/field-safety.md, docs/signing.md):

* MAVLink 2 signing (``signing_key=``, :mod:`fleetctl.mavlink.signing`): everything sent is signed
  (``link_id``, a strictly increasing timestamp persisted in ``signing_state``); incoming messages
  that are unsigned (RADIO_STATUS excepted), wrongly signed or replayed are dropped before anything
  sees them and counted in :attr:`Link.rejected`.
* Messages with source system id 0 (the broadcast address; PX4 sends some) are dropped and
  counted in :attr:`Link.rx_sysid0`: no vehicle has that id.
* Routes: once a system id was heard from an address, a message with that system id from another
  address is dropped (it neither moves the route nor reaches a subscriber) unless the old address
  has been silent for ``route_timeout`` seconds; each such conflict is counted
  (:attr:`Link.route_conflicts`), logged and passed to :attr:`Link.on_route_conflict`.
* Dispatch is by source system id and message type (dict lookups); subscriptions are
  copy-on-write, so a message costs the same with 1 or 200 vehicles on the link.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import secrets
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any, cast

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from fleetctl.aio import cancel_and_wait
from fleetctl.mavlink import mission_protocol
from fleetctl.mavlink.address import LinkAddress, parse_url
from fleetctl.mavlink.command_protocol import (
    COMMAND_PROGRESS_TIMEOUT,
    COMMAND_RETRIES,
    COMMAND_TIMEOUT,
    send_command,
    set_message_interval,
)
from fleetctl.mavlink.errors import LinkError, LinkTimeout, MissionRejected
from fleetctl.mavlink.expectations import Inbox, Waiter
from fleetctl.mavlink.messages import CommandAck, MissionItem, command_name, enum_name
from fleetctl.mavlink.rtt import RoundTrip
from fleetctl.mavlink.signing import (
    OK,
    REJECTION_KEYS,
    Signer,
    SigningKey,
    TimestampStore,
    Verifier,
    state_path,
)

log = logging.getLogger(__name__)

M = mavlink2
GCS_SYSID = 255
GCS_COMPID = M.MAV_COMP_ID_MISSIONPLANNER  # 190

MAX_PEERS = 64
ROUTE_TIMEOUT = 3.0  # s: a system id's route moves to a new address only after this much silence
_CONFLICT_LOG_S = 10.0  # s between two warnings about the same route conflict

Tap = Callable[[str, float, bytes], None]
Handler = Callable[[Any], None]
RouteConflict = Callable[[int, Any, Any], None]


# ------------------------------------------------------------------------------------ transports


class _Udp(asyncio.DatagramProtocol):
    def __init__(self, link: Link) -> None:
        self.link = link
        self.transport: asyncio.DatagramTransport | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        # asyncio hands a datagram protocol its DatagramTransport; typeshed declares the base class
        self.transport = cast(asyncio.DatagramTransport, transport)

    def datagram_received(self, data: bytes, addr: Any) -> None:
        self.link._received(data, addr)

    def error_received(self, exc: Exception) -> None:
        log.debug("%s: %s", self.link.url, exc)  # e.g. ICMP port unreachable before the vehicle is up

    def connection_lost(self, exc: Exception | None) -> None:
        self.transport = None


def _new_parser() -> Any:
    p = M.MAVLink(None)
    p.robust_parsing = True
    return p


# ------------------------------------------------------------------------------------ the link


class Link:
    """One MAVLink 2 connection (a URL) carrying any number of vehicles, told apart by system id.

    ``async with Link("udp://127.0.0.1:14550") as link:`` opens it and starts the 1 Hz GCS
    heartbeat; ``close()`` cancels every background task and pending expectation.
    """

    def __init__(self, url: str, *, sysid: int = GCS_SYSID, compid: int = GCS_COMPID,
                 heartbeat_hz: float = 1.0, signing_key: SigningKey | None = None, link_id: int = 0,
                 signing_state: str | Path | None | bool = None, route_timeout: float = ROUTE_TIMEOUT,
                 on_route_conflict: RouteConflict | None = None) -> None:
        """``signing_key`` turns signing on (see the module docstring); ``link_id`` tells this
        link's signed stream from the controller's others; ``signing_state`` is where the outgoing
        timestamp is persisted: a file, a directory (e.g. the run folder: ``signing-<key id>.json``
        in it), None = ``~/.local/state/fleetctl/signing-<key id>.json``, False = not persisted."""
        self.address = parse_url(url)
        self.url = url
        self.sysid = sysid
        self.compid = compid
        self.heartbeat_hz = heartbeat_hz
        self.mav = M.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.routes: dict[int, Any] = {}  # remote sysid -> address it was last heard from
        self.last_heard: dict[int, float] = {}  # remote sysid -> time.monotonic()
        self.nonce = secrets.randbits(32)  # in our GCS heartbeat's custom_mode: tells ours from others'
        self.other_gcs: dict[tuple[int, int, int], float] = {}  # other ground stations heard -> when
        self.rx_messages = 0
        self.rx_bad = 0
        self.rx_sysid0 = 0  # messages with source system id 0 (dropped: not a vehicle)
        self.tx_messages = 0
        self._peers: dict[Any, float] = {}
        self._parsers: dict[Any, Any] = {}
        self._udp: _Udp | None = None
        self._writer: asyncio.StreamWriter | None = None
        self._tasks: set[asyncio.Task[Any]] = set()
        self._taps: list[Tap] = []
        self._subs: list[tuple[int | None, frozenset[str] | None, Handler]] = []
        # copy-on-write index of _subs: source sysid (None = any) -> type (None = any) -> handlers
        self._sub_index: dict[int | None, dict[str | None, tuple[Handler, ...]]] = {}
        self._any_src: dict[str | None, tuple[Handler, ...]] | None = None
        self._waiters: dict[str, list[Waiter]] = {}
        self._locks: dict[Any, asyncio.Lock] = {}
        self._open = False
        self.mission_rtt = 0.0  # of the last mission exchange; sets the item timeout of a download
        self.rtt = RoundTrip()  # the commands' round trips: how long an attempt waits before a resend
        self.route_timeout = route_timeout
        self.on_route_conflict = on_route_conflict
        self.route_conflicts = 0
        self._conflict_logged: dict[tuple[int, Any], float] = {}
        self.rejected: dict[str, int] = dict.fromkeys(REJECTION_KEYS.values(), 0)
        self.rejected_from: dict[int, dict[str, int]] = {}  # sysid -> signing rejections of its messages
        self.signer: Signer | None = None
        self._verifier: Verifier | None = None
        if signing_key is not None:
            self.enable_signing(signing_key, link_id=link_id, state=signing_state)

    # -- signing ---------------------------------------------------------------------------------
    def enable_signing(self, key: SigningKey, *, link_id: int = 0,
                       state: str | Path | None | bool = None, verify: bool = True) -> None:
        """Sign everything sent from now on and drop unsigned/badly signed/replayed messages
        (``verify=False``: sign only, accept anything - for provisioning vehicles without a key)."""
        if self.signer is not None:
            self.signer.close()
        store = None
        if state is not False:
            store = TimestampStore(state_path(key, None if state is True else state), key.fingerprint)
        self.signer = Signer(self.mav, key, link_id, store)
        signer = self.signer
        self._verifier = Verifier(key, seen=signer.seen) if verify else None
        log.info("%s: signing on (key %s, link id %d)", self.url, key.fingerprint, link_id)

    def disable_signing(self) -> None:
        """Back to unsigned traffic (e.g. after provisioning an all-zero key)."""
        if self.signer is not None:
            self.signer.close()
        self.signer = None
        self._verifier = None
        s = self.mav.signing
        s.sign_outgoing = False
        s.secret_key = None

    @property
    def signing(self) -> bool:
        return self.signer is not None

    # -- lifecycle -----------------------------------------------------------------------------
    async def open(self, timeout: float = 5.0) -> Link:
        """Open the transport and start the GCS heartbeat; :class:`LinkError` if that fails."""
        if self._open:
            return self
        a = self.address
        loop = asyncio.get_running_loop()
        try:
            if a.kind == "udpin":
                await loop.create_datagram_endpoint(lambda: self._make_udp(), local_addr=(a.host, a.port))
            elif a.kind == "udpout":
                local = "127.0.0.1" if a.host.startswith("127.") or a.host == "localhost" else "0.0.0.0"
                await loop.create_datagram_endpoint(lambda: self._make_udp(), local_addr=(local, 0))
                self._peers[(a.host, a.port)] = time.monotonic()
            elif a.kind == "tcp":
                async with asyncio.timeout(timeout):
                    reader, writer = await asyncio.open_connection(a.host, a.port)
                self._start_stream(reader, writer, reconnect=True)
            else:
                reader, writer = await self._open_serial(timeout)
                self._start_stream(reader, writer, reconnect=False)
        except TimeoutError:
            raise LinkError(f"connection {self.url!r}: no answer within {timeout:g} s") from None
        except OSError as exc:
            raise LinkError(f"connection {self.url!r}: cannot open ({exc.strerror or exc}); "
                            "check the address, or stop what uses that port") from None
        self._open = True
        if self.heartbeat_hz > 0:
            self._spawn(self._heartbeat_loop(), "heartbeat")
        log.info("link %s open", self.url)
        return self

    def _make_udp(self) -> _Udp:
        self._udp = _Udp(self)
        return self._udp

    async def _open_serial(self, timeout: float) -> tuple[asyncio.StreamReader, asyncio.StreamWriter]:
        try:
            import serial_asyncio
        except ImportError:
            raise LinkError(f"connection {self.url!r}: serial links need the pyserial-asyncio package "
                            "(pip install pyserial-asyncio)") from None
        try:
            async with asyncio.timeout(timeout):
                return await serial_asyncio.open_serial_connection(url=self.address.device,
                                                                   baudrate=self.address.baud)
        except Exception as exc:  # serial.SerialException is not an OSError
            if isinstance(exc, TimeoutError):
                raise
            raise LinkError(f"connection {self.url!r}: cannot open {self.address.device} ({exc})") from None

    def _start_stream(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter,
                      reconnect: bool) -> None:
        self._writer = writer
        self._spawn(self._read_stream(reader, writer, reconnect), "reader")

    async def _read_stream(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter,
                           reconnect: bool) -> None:
        addr = self.address.device or (self.address.host, self.address.port)
        while True:
            try:
                while data := await reader.read(4096):
                    self._received(data, addr)
            except (OSError, asyncio.IncompleteReadError) as exc:
                log.warning("%s: read failed: %s", self.url, exc)
            self._writer = None
            with contextlib.suppress(Exception):
                writer.close()
            self._parsers.pop(addr, None)
            if not reconnect:
                log.warning("%s: closed by the other side", self.url)
                return
            log.warning("%s: connection dropped; reconnecting", self.url)
            while True:
                await asyncio.sleep(1.0)
                try:
                    async with asyncio.timeout(5.0):
                        reader, writer = await asyncio.open_connection(self.address.host, self.address.port)
                    self._writer = writer
                    log.info("%s: reconnected", self.url)
                    break
                except (OSError, TimeoutError) as exc:
                    log.debug("%s: reconnect failed: %s", self.url, exc)

    def _spawn(self, coro: Any, name: str) -> None:
        task = asyncio.get_running_loop().create_task(coro, name=f"link {self.url} {name}")
        self._tasks.add(task)
        task.add_done_callback(self._task_done)

    def _task_done(self, task: asyncio.Task[Any]) -> None:
        self._tasks.discard(task)
        if not task.cancelled() and task.exception() is not None:
            log.error("%s: background task %s failed", self.url, task.get_name(), exc_info=task.exception())

    async def close(self) -> None:
        """Stop the heartbeat and readers, fail pending expectations, close the transport."""
        self._open = False
        if self.signer is not None:
            self.signer.close()
        await cancel_and_wait(*self._tasks)
        for waiters in self._waiters.values():
            for w in waiters:
                if w.fut is not None and not w.fut.done():
                    w.fut.cancel()
        self._waiters.clear()
        if self._udp is not None and self._udp.transport is not None:
            self._udp.transport.close()
        self._udp = None
        if self._writer is not None:
            self._writer.close()
            with contextlib.suppress(Exception):
                async with asyncio.timeout(1.0):
                    await self._writer.wait_closed()
            self._writer = None

    async def __aenter__(self) -> Link:
        return await self.open()

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    @property
    def is_open(self) -> bool:
        return self._open

    @property
    def local_port(self) -> int | None:
        """The local UDP port (useful with ``udpin://HOST:0``)."""
        if self._udp is None or self._udp.transport is None:
            return None
        return int(self._udp.transport.get_extra_info("sockname")[1])

    # -- observers -------------------------------------------------------------------------------
    def add_tap(self, tap: Tap) -> Callable[[], None]:
        """Call ``tap(direction, unix_time, raw_bytes)`` for every message ("in" and "out").
        Returns a function that removes the tap."""
        self._taps.append(tap)
        return lambda: self._taps.remove(tap) if tap in self._taps else None

    def subscribe(self, handler: Handler, *, sysid: int | None = None,
                  types: Iterable[str] | None = None) -> Callable[[], None]:
        """Call ``handler(msg)`` for messages from ``sysid`` (None = any) of ``types`` (None = all).
        Returns a function that unsubscribes."""
        entry = (sysid, None if types is None else frozenset(types), handler)
        self._subs = [*self._subs, entry]
        self._reindex()

        def unsubscribe() -> None:
            if entry in self._subs:
                self._subs = [e for e in self._subs if e is not entry]
                self._reindex()

        return unsubscribe

    def _reindex(self) -> None:
        """Rebuild the dispatch index (copy-on-write: a message in flight keeps the old one)."""
        index: dict[int | None, dict[str | None, list[Handler]]] = {}
        for sysid, types, handler in self._subs:
            per = index.setdefault(sysid, {})
            for t in (None,) if types is None else sorted(types):
                per.setdefault(t, []).append(handler)
        self._sub_index = {s: {t: tuple(hs) for t, hs in per.items()} for s, per in index.items()}
        self._any_src = self._sub_index.get(None)

    # -- receive -----------------------------------------------------------------------------------
    def _received(self, data: bytes, addr: Any) -> None:
        parser = self._parsers.get(addr)
        if parser is None:
            if len(self._parsers) >= MAX_PEERS:
                self._parsers.pop(next(iter(self._parsers)))
            parser = self._parsers[addr] = _new_parser()
        if self.address.kind == "udpin":
            if addr not in self._peers and len(self._peers) >= MAX_PEERS:
                del self._peers[min(self._peers, key=self._peers.__getitem__)]
            self._peers[addr] = time.monotonic()
        try:
            msgs = parser.parse_buffer(data) or []
        except Exception as exc:  # noqa: BLE001 - garbage on the wire must not kill the link
            log.debug("%s: undecodable data from %s: %s", self.url, addr, exc)
            self.rx_bad += 1
            self._parsers[addr] = _new_parser()
            return
        if self._udp is not None and parser.buf_len() > 0:
            # a UDP datagram is self-contained: a partial (truncated) message left in the parser
            # would swallow the start of the next good datagram from this peer
            self.rx_bad += 1
            self._parsers[addr] = _new_parser()
        for msg in msgs:
            self._dispatch(msg, addr)

    def _dispatch(self, msg: Any, addr: Any) -> None:
        mtype = msg.get_type()
        if mtype == "BAD_DATA":
            self.rx_bad += 1
            return
        src = msg.get_srcSystem()
        if src == 0:
            # 0 is the broadcast address, never a sender's: PX4 sends some messages (ids outside the
            # common dialect) with it from every instance. Not a vehicle: no route, no subscriber,
            # and no route conflict between the vehicles that all send it
            self.rx_sysid0 += 1
            return
        if mtype == "HEARTBEAT" and msg.type == M.MAV_TYPE_GCS:  # a ground station, not a vehicle
            if self._taps:
                self._tap("in", msg.get_msgbuf())
            self._gcs_heartbeat(msg)
            return
        if src == self.sysid and msg.get_srcComponent() == self.compid:
            return  # our own traffic reflected back
        verifier = self._verifier
        if verifier is not None:
            verdict = verifier.check(msg.get_msgbuf())
            if verdict != OK:
                why = REJECTION_KEYS[verdict]
                self.rejected[why] += 1
                if src in self.rejected_from or len(self.rejected_from) < MAX_PEERS:
                    counts = self.rejected_from.setdefault(src, {})
                    counts[why] = counts.get(why, 0) + 1
                return
        now = time.monotonic()
        route = self.routes.get(src)
        if route != addr:
            if route is not None and now - self.last_heard.get(src, 0.0) <= self.route_timeout:
                self._route_conflict(src, route, addr, now)
                return
            if route is not None:
                log.warning("%s: system %d now heard from %s (silent at %s for %.1f s)", self.url, src,
                            addr, route, now - self.last_heard.get(src, 0.0))
            self.routes[src] = addr
        self.rx_messages += 1
        self.last_heard[src] = now
        if self._taps:
            self._tap("in", msg.get_msgbuf())
        waiters = self._waiters.get(mtype)
        if waiters and getattr(msg, "target_system", 0) in (0, self.sysid):
            for w in list(waiters):
                if w.offer(msg):
                    self._remove_waiter(w)
        for per in (self._sub_index.get(src), self._any_src):  # this sender's, then any sender's
            if per is None:
                continue
            for key in (mtype, None):  # this message type's handlers, then all-types handlers
                hs = per.get(key)
                if hs is not None:
                    self._call(hs, msg, src)

    def _call(self, handlers: tuple[Handler, ...], msg: Any, src: int) -> None:
        for handler in handlers:
            try:
                handler(msg)
            except Exception:  # noqa: BLE001 - one faulty subscriber must not starve others
                log.exception("%s: handler failed on %s from %d", self.url, msg.get_type(), src)

    def _route_conflict(self, sysid: int, old: Any, new: Any, now: float) -> None:
        """A message with a known system id from an address other than its route: dropped."""
        self.route_conflicts += 1
        key = (sysid, new)
        if now - self._conflict_logged.get(key, -math.inf) >= _CONFLICT_LOG_S:
            if len(self._conflict_logged) > 1024:
                self._conflict_logged.clear()
            self._conflict_logged[key] = now
            log.warning("%s: system %d heard from %s while its route is %s (heard %.1f s ago): ignored "
                        "(spoofing, or a second path; the route moves after %.1f s of silence)",
                        self.url, sysid, new, old, now - self.last_heard.get(sysid, 0.0), self.route_timeout)
        cb = self.on_route_conflict
        if cb is not None:
            try:
                cb(sysid, old, new)
            except Exception:  # noqa: BLE001
                log.exception("%s: route conflict callback failed", self.url)

    def _gcs_heartbeat(self, msg: Any) -> None:
        """Another ground station's heartbeat (not ours reflected back: its nonce differs)."""
        src, comp = msg.get_srcSystem(), msg.get_srcComponent()
        if src == self.sysid and comp == self.compid and msg.custom_mode == self.nonce:
            return
        self.other_gcs[(src, comp, msg.custom_mode)] = time.monotonic()

    def why_silent(self, sysid: int, expected: Iterable[int] = ()) -> str:
        """Why no HEARTBEAT of ``sysid`` was taken on this link, from what the link did hear: its
        messages refused by signing, other system ids, or no traffic at all."""
        refused = self.rejected_from.get(sysid)
        if refused:
            key = max(refused, key=refused.__getitem__)
            return _REFUSED_WHY[key].format(n=refused[key])
        if sysid in self.last_heard:
            return "its messages arrive, but no HEARTBEAT among them"
        known = set(expected)
        others = sorted(s for s in self.last_heard if s not in known and s != sysid)
        if others:
            ids = ", ".join(str(s) for s in others[:8])
            return (f"heard system id(s) {ids}, which the mission does not name, but not {sysid}: "
                    "check the vehicle's system id")
        if not self.last_heard and not self.rx_bad and not any(self.rejected.values()):
            return "no MAVLink traffic at all on this link: check the URL and that the vehicle is powered"
        return "not heard: check the system id and that the vehicle is powered"

    def other_ground_stations(self, within: float = 5.0) -> list[tuple[int, int]]:
        """(sysid, compid) of every other ground station heard on this link in the last ``within`` s."""
        now = time.monotonic()
        return sorted({(s, c) for (s, c, _n), t in self.other_gcs.items() if now - t <= within})

    def _tap(self, direction: str, data: bytes) -> None:
        ts = time.time()
        for tap in list(self._taps):
            try:
                tap(direction, ts, bytes(data))
            except Exception:  # noqa: BLE001
                log.exception("%s: tap failed", self.url)

    # -- send ----------------------------------------------------------------------------------------
    def send(self, msg: Any, sysid: int | None = None) -> None:
        """Encode and send ``msg`` (built with ``link.mav.<name>_encode``) to the address ``sysid``
        was last heard from; ``sysid=None`` broadcasts (every peer of a udpin link)."""
        if self.signer is not None:
            self.signer.stamp()
        data = msg.pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) & 0xFF
        self.tx_messages += 1
        if self._taps:
            self._tap("out", data)
        if self._writer is not None:
            self._writer.write(data)
            return
        udp = self._udp
        if udp is None or udp.transport is None:
            log.debug("%s: not open, %s dropped", self.url, msg.get_type())
            return
        addr = self.routes.get(sysid) if sysid else None
        if addr is not None:
            udp.transport.sendto(data, addr)
            return
        if not self._peers:
            log.debug("%s: nobody heard yet, %s not sent", self.url, msg.get_type())
        for peer in list(self._peers):
            udp.transport.sendto(data, peer)

    async def _heartbeat_loop(self) -> None:
        period = 1.0 / self.heartbeat_hz
        while True:
            self.send(self.mav.heartbeat_encode(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, self.nonce,
                                                M.MAV_STATE_ACTIVE))
            await asyncio.sleep(period)

    # -- request / response ----------------------------------------------------------------------------
    def _register(self, w: Waiter) -> None:
        for t in w.types:
            self._waiters.setdefault(t, []).append(w)

    def _remove_waiter(self, w: Waiter) -> None:
        for t in w.types:
            lst = self._waiters.get(t)
            if lst is not None and w in lst:
                lst.remove(w)
                if not lst:
                    del self._waiters[t]

    def expect(self, types: str | Iterable[str], *, sysid: int | None = None,
               match: Callable[[Any], bool] | None = None) -> asyncio.Future[Any]:
        """A future for the next message of ``types`` from ``sysid`` addressed to us (or broadcast)
        for which ``match(msg)`` holds. Register it before sending the request; cancelling the
        future (e.g. ``asyncio.wait_for`` timing out) unregisters it."""
        fut: asyncio.Future[Any] = asyncio.get_running_loop().create_future()
        w = Waiter(frozenset([types] if isinstance(types, str) else types), sysid, match, fut, None)
        self._register(w)
        fut.add_done_callback(lambda _f: self._remove_waiter(w))
        return fut

    @contextlib.contextmanager
    def collect(self, types: str | Iterable[str], *, sysid: int | None = None,
                match: Callable[[Any], bool] | None = None) -> Iterator[Inbox]:
        """``with link.collect(...) as inbox:`` queues every matching message until the block ends
        (for exchanges with several replies: command progress, mission transfers)."""
        queue: asyncio.Queue[Any] = asyncio.Queue()
        w = Waiter(frozenset([types] if isinstance(types, str) else types), sysid, match, None, queue)
        self._register(w)
        try:
            yield Inbox(queue)
        finally:
            self._remove_waiter(w)

    async def request(self, msg: Any, sysid: int, types: str | Iterable[str], *,
                      match: Callable[[Any], bool] | None = None, timeout: float = 1.0) -> Any:
        """Send ``msg`` to ``sysid`` once and return the first matching reply (``TimeoutError``)."""
        fut = self.expect(types, sysid=sysid, match=match)
        self.send(msg, sysid)
        return await asyncio.wait_for(fut, timeout)

    def lock(self, key: Any) -> asyncio.Lock:
        """One exchange of a kind at a time (``key``: e.g. a command and a vehicle)."""
        lock = self._locks.get(key)
        if lock is None:
            lock = self._locks[key] = asyncio.Lock()
        return lock

    # -- commands ------------------------------------------------------------------------------------------
    async def command(
        self, sysid: int, command: int, params: Iterable[float] = (), *, compid: int = 1,
        frame: int | None = None, timeout: float = COMMAND_TIMEOUT, retries: int = COMMAND_RETRIES,
        progress_timeout: float = COMMAND_PROGRESS_TIMEOUT,
    ) -> CommandAck:
        """Send a command; its final :class:`CommandAck`
        (:func:`fleetctl.mavlink.command_protocol.send_command`)."""
        return await send_command(self, sysid, command, params, compid=compid, frame=frame, timeout=timeout,
                                  retries=retries, progress_timeout=progress_timeout)

    async def set_message_interval(self, sysid: int, msgid: int, hz: float, *, compid: int = 1,
                                   retries: int = COMMAND_RETRIES) -> CommandAck:
        """Stream ``msgid`` at ``hz`` (0 = the default rate, < 0 = off)."""
        return await set_message_interval(self, sysid, msgid, hz, compid=compid, retries=retries)

    # -- mission protocol ------------------------------------------------------------------------------------
    async def upload_mission(self, sysid: int, items: list[MissionItem], **options: Any) -> None:
        """Upload ``items`` (:func:`fleetctl.mavlink.mission_protocol.upload_mission`)."""
        await mission_protocol.upload_mission(self, sysid, items, **options)

    async def download_mission(self, sysid: int, **options: Any) -> list[MissionItem]:
        """The vehicle's mission (:func:`fleetctl.mavlink.mission_protocol.download_mission`)."""
        return await mission_protocol.download_mission(self, sysid, **options)

    async def clear_mission(self, sysid: int, **options: Any) -> None:
        """MISSION_CLEAR_ALL (:func:`fleetctl.mavlink.mission_protocol.clear_mission`)."""
        await mission_protocol.clear_mission(self, sysid, **options)


_REFUSED_WHY = {
    "rejected_unsigned": "heard, but unsigned ({n} messages refused): signing is on; provision its key "
                         "with 'fleetctl keys provision'",
    "rejected_bad_signature": "heard, but signed with another key ({n} messages refused): provision the "
                              "mission's key",
    "rejected_replay": "heard, but its signing timestamps go back ({n} messages refused: a replay, or "
                       "the vehicle's clock was reset)",
}


__all__ = [
    "CommandAck",
    "GCS_COMPID",
    "GCS_SYSID",
    "Inbox",
    "Link",
    "LinkAddress",
    "LinkError",
    "LinkTimeout",
    "MissionItem",
    "MissionRejected",
    "command_name",
    "enum_name",
    "parse_url",
]
