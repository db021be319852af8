"""The UDP side of the JSON interface: one socket per firmware instance (the port its servo
packets go to, 9002 + 10 * instance unless told otherwise), served by one thread that blocks in
``select`` and answers every servo packet, in lockstep, with the state after one physics step of
``1 / frame_rate``.

A repeated frame count (the firmware re-sends after a second without an answer) gets the last
answer again without stepping; a smaller frame count means the firmware restarted, and its
vehicle goes back to its start state.

One world clock: each firmware runs its own lockstep clock, and on a loaded machine one process
can run seconds ahead of another. A copter riding a deck reads its carrier's state, so a carrier
ahead of (or behind) the copter would move the copter in jumps its own IMU never felt (ArduCopter
reports ``GPS Glitch`` and refuses to arm). The server therefore holds back the answer to a
vehicle more than ``max_skew`` simulated seconds ahead of the slowest active one (one that sent
within ``active_timeout`` wall seconds) until that one catches up. A vehicle that starts (or
restarts) later joins at the world's time; one that falls silent (killed) stops holding the
others after ``active_timeout``."""

from __future__ import annotations

import selectors
import socket
import threading
import time
from dataclasses import dataclass

from .protocol import encode_state, parse_servo
from .sockets import ServingThread, listen_all
from .world import World

BASE_PORT = 9002
MAX_SKEW = 0.02        # simulated s one vehicle may run ahead of the slowest active one
ACTIVE_TIMEOUT = 2.0   # wall s: a vehicle silent this long no longer holds the others back


def servo_port(instance: int) -> int:
    """Where ArduPilot instance ``instance`` with ``--model JSON`` sends its servo outputs."""
    return BASE_PORT + 10 * instance


@dataclass
class LinkStats:
    packets: int = 0      # servo packets answered with a new step
    repeats: int = 0      # repeated frames answered again
    resets: int = 0       # firmware restarts seen
    malformed: int = 0    # datagrams that were no servo packet
    frame_rate: int = 0   # the firmware's physics rate (Hz) in its last packet
    held: int = 0         # times its packet waited for a slower vehicle (the world's clock)


@dataclass
class _Link:
    name: str
    sock: socket.socket
    stats: LinkStats
    last_count: int = -1
    last_reply: bytes = b""
    pending: tuple[int, bytes, tuple[str, int]] | None = None  # frame count, packet, sender: not answered yet
    heard: float = -1e9   # wall (monotonic) time of its last packet
    offset: float = 0.0   # world time at which this firmware's clock started


class JsonServer(ServingThread):
    """Serves the firmware instances of ``world`` from a background thread (``start``/``stop``).
    ``lock`` guards the world: hold it to read vehicle states from another thread."""

    def __init__(self, world: World, host: str = "127.0.0.1", ports: dict[str, int] | None = None, *,
                 max_skew: float = MAX_SKEW, active_timeout: float = ACTIVE_TIMEOUT) -> None:
        self.world = world
        self.max_skew = max_skew
        self.active_timeout = active_timeout
        self.host = host
        self.ports = {n: (ports or {}).get(n, servo_port(v.instance)) for n, v in world.vehicles.items()}
        self.lock = threading.Lock()
        self.stats = {n: LinkStats() for n in world.vehicles}
        self._links: list[_Link] = []
        super().__init__("json-physics")

    def start(self) -> JsonServer:
        socks = listen_all(socket.SOCK_DGRAM, self.host, self.ports, "its firmware's servo packets")
        for name, s in socks.items():
            link = _Link(name, s, self.stats[name])
            self._links.append(link)
            self._selector.register(s, selectors.EVENT_READ, link)
        self._launch()
        return self

    def stop(self) -> None:
        self._halt()
        self._selector.close()
        for link in self._links:
            link.sock.close()
        self._links.clear()

    def _run(self) -> None:
        while not self._stopping.is_set():
            waiting = any(link.pending is not None for link in self._links)
            for key, _ in self._selector.select(timeout=0.05 if waiting else 0.2):
                link: _Link = key.data
                while True:
                    try:
                        data, addr = link.sock.recvfrom(512)
                    except (BlockingIOError, InterruptedError):
                        break
                    except OSError:
                        break
                    self.receive(link, data, addr, time.monotonic())
            self.serve(time.monotonic())

    def _send(self, link: _Link, reply: bytes, addr: tuple[str, int]) -> None:
        if reply:
            try:
                link.sock.sendto(reply, addr)
            except OSError:
                pass

    def world_time(self, link: _Link) -> float:
        return link.offset + self.world.vehicles[link.name].time

    def receive(self, link: _Link, data: bytes, addr: tuple[str, int], now: float) -> None:
        """A datagram from a firmware: a repeat of the frame last answered gets that answer again
        at once; a new frame waits in ``pending`` for :meth:`serve`."""
        pkt = parse_servo(data)
        if pkt is None or pkt.frame_rate <= 0:
            link.stats.malformed += 1
            return
        link.heard = now
        if pkt.frame_count == link.last_count and link.last_reply:
            link.stats.repeats += 1
            self._send(link, link.last_reply, addr)
            return
        link.pending = (pkt.frame_count, data, addr)

    def serve(self, now: float) -> None:
        """Answer the pending packets, slowest vehicle first, each while its vehicle is at most
        ``max_skew`` ahead of the slowest other active vehicle; a firmware that starts or restarts
        joins at once, at the world's time."""
        while True:
            waiting = [link for link in self._links if link.pending is not None]
            if not waiting:
                return

            def joining(k: _Link) -> bool:
                return k.last_count < 0 or (k.pending is not None and k.pending[0] < k.last_count)
            link = min(waiting, key=lambda k: -1.0 if joining(k) else self.world_time(k))
            others = [self.world_time(k) for k in self._links
                      if k is not link and not joining(k)
                      and (k.pending is not None or now - k.heard <= self.active_timeout)]
            floor = min(others, default=None)
            ahead = floor is not None and self.world_time(link) > floor + self.max_skew + 1e-9
            if ahead and not joining(link):
                link.stats.held += 1
                return
            assert link.pending is not None
            _, data, addr = link.pending
            link.pending = None
            self._send(link, self.handle(link, data, floor), addr)

    def handle(self, link: _Link, data: bytes, world_time: float | None = None) -> bytes:
        """Step the link's vehicle by one packet and return the answer (``world_time``: the world
        clock, where a firmware that starts or restarts now joins it)."""
        pkt = parse_servo(data)
        if pkt is None or pkt.frame_rate <= 0:
            link.stats.malformed += 1
            return b""
        if pkt.frame_count == link.last_count and link.last_reply:
            link.stats.repeats += 1
            return link.last_reply
        with self.lock:
            if pkt.frame_count < link.last_count:
                link.stats.resets += 1
                self.world.reset(link.name)
            if pkt.frame_count < link.last_count or link.last_count < 0:
                link.offset = world_time or 0.0
            v = self.world.vehicles[link.name]
            body = self.world.step(link.name, pkt.pwm, 1.0 / pkt.frame_rate)
            link.last_reply = encode_state(v.time, body, v.start)
        link.last_count = pkt.frame_count
        link.stats.packets += 1
        link.stats.frame_rate = pkt.frame_rate
        return link.last_reply
