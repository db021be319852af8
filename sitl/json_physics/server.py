"""The UDP side of the JSON interface: one socket per firmware instance (the port its servo
packets go to, 9002 + 10 * instance unless told otherwise), served by one thread that blocks in
``select`` and answers every servo packet, in lockstep, with the state after one physics step of
``1 / frame_rate``.

A repeated frame count (the firmware re-sends after a second without an answer) gets the last
answer again without stepping; a smaller frame count means the firmware restarted, and its
vehicle goes back to its start state."""

from __future__ import annotations

import selectors
import socket
import threading
from dataclasses import dataclass

from .protocol import encode_state, parse_servo
from .world import World

BASE_PORT = 9002


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


@dataclass
class _Link:
    name: str
    sock: socket.socket
    stats: LinkStats
    last_count: int = -1
    last_reply: bytes = b""


class JsonServer:
    """Serves the firmware instances of ``world`` from a background thread (``start``/``stop``).
    ``lock`` guards the world: hold it to read vehicle states from another thread."""

    def __init__(self, world: World, host: str = "127.0.0.1", ports: dict[str, int] | None = None) -> None:
        self.world = world
        self.host = host
        self.ports = {n: (ports or {}).get(n, servo_port(v.instance)) for n, v in world.vehicles.items()}
        self.lock = threading.Lock()
        self.stats = {n: LinkStats() for n in world.vehicles}
        self._links: list[_Link] = []
        self._selector = selectors.DefaultSelector()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> JsonServer:
        for name, port in self.ports.items():
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            s.bind((self.host, port))
            s.setblocking(False)
            link = _Link(name, s, self.stats[name])
            self._links.append(link)
            self._selector.register(s, selectors.EVENT_READ, link)
        self._thread = threading.Thread(target=self._run, name="json-physics", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5.0)
        self._selector.close()
        for link in self._links:
            link.sock.close()
        self._links.clear()

    def _run(self) -> None:
        while not self._stop.is_set():
            for key, _ in self._selector.select(timeout=0.2):
                link: _Link = key.data
                while True:
                    try:
                        data, addr = link.sock.recvfrom(512)
                    except (BlockingIOError, InterruptedError):
                        break
                    except OSError:
                        break
                    reply = self.handle(link, data)
                    if reply:
                        try:
                            link.sock.sendto(reply, addr)
                        except OSError:
                            pass

    def handle(self, link: _Link, data: bytes) -> bytes:
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
            v = self.world.vehicles[link.name]
            body = self.world.step(link.name, pkt.pwm, 1.0 / pkt.frame_rate)
            link.last_reply = encode_state(v.time, body, v.start)
        link.last_count = pkt.frame_count
        link.stats.packets += 1
        link.stats.frame_rate = pkt.frame_rate
        return link.last_reply
