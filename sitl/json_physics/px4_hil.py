"""PX4's simulator interface (``simulator_mavlink``): the same world flown by PX4 firmware.

PX4 SITL started with ``PX4_SIMULATOR=rotorpy`` (an external simulator; GPS, barometer and
magnetometer simulated inside PX4 from the ground truth it is sent) connects over TCP to port
``4560 + instance`` and speaks MAVLink 2 there. The world answers with, each step of
``1 / rate`` simulated seconds:

- ``HIL_SENSOR``: the accelerometer and gyroscope (body FRD, m/s^2 and rad/s, with a little
  noise: PX4 flags a sensor whose readings repeat exactly as stale; and the vibration of a ground
  vehicle that drives, felt by the copters on its deck too: PX4 takes a landed vehicle whose IMU
  is quiet to be at rest, holds its estimate still and fails its GPS drift checks when it moves,
  so a copter riding a smooth simulated deck could not be armed at the next stop);
- ``HIL_STATE_QUATERNION``: the ground truth (attitude, position, velocity) from which PX4's
  own ``sensor_gps_sim``, ``sensor_baro_sim`` and ``sensor_mag_sim`` compute those sensors;

and takes ``HIL_ACTUATOR_CONTROLS`` (motors 0..1, other outputs -1..1) for the next step.

Lockstep: PX4's clock is the ``time_usec`` the world sends. All vehicles step together on one
world clock, paced at ``speed`` times real time. A firmware answers at its own control rate (a
quad every step, the rover every few) with its own time in the controls; a step waits (at most
``reply_timeout`` wall seconds) for a firmware whose last answer is more than ``MAX_LAG`` behind
the world, so a loaded machine slows the world rather than leaving the firmware behind it. A
firmware that does not answer in time is not waited for again until it answers. A firmware that
connects later joins at the world's time; one whose connection closes (killed) leaves its
vehicle with motors off.
"""

from __future__ import annotations

import math
import random
import selectors
import socket
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import common as mavlink2

from ..geo import LocalFrame
from .rigid import GRAVITY
from .sockets import ServingThread, listen_all
from .world import World

BASE_PORT = 4560
RATE = 250                 # Hz: PX4's IMU_INTEG_RATE for its simulator airframes
REPLY_TIMEOUT = 0.05       # wall s a step waits for a firmware's controls
MAX_LAG = 0.02             # simulated s a firmware's controls may lag the world without a wait
MAX_BEHIND = 1.0           # wall s the world may fall behind its pace and still catch up
ACCEL_NOISE = 0.02         # m/s^2 (1 sigma)
GYRO_NOISE = 0.002         # rad/s
VIBRATION_ACCEL = 1.0      # m/s^2 (1 sigma) more on a ground vehicle driving at VIBRATION_SPEED or faster
VIBRATION_GYRO = 0.1       # rad/s more, likewise
VIBRATION_SPEED = 1.0      # m/s
MAX_READ = 65536           # bytes read from one firmware per pass


def hil_port(instance: int) -> int:
    """Where PX4 instance ``instance`` connects to its simulator."""
    return BASE_PORT + instance


@dataclass
class HilStats:
    steps: int = 0         # sensor messages sent
    controls: int = 0      # HIL_ACTUATOR_CONTROLS received
    waits: int = 0         # steps that ran without this firmware's answer (timeout)
    connects: int = 0
    malformed: int = 0     # bytes MAVLink could not parse


@dataclass
class _Link:
    name: str
    listener: socket.socket
    stats: HilStats
    conn: socket.socket | None = None
    mav: mavlink2.MAVLink = field(default_factory=lambda: mavlink2.MAVLink(None, 1, 51))
    controls: tuple[float, ...] = (0.0,) * 16
    answered_at: float = -1.0  # the firmware's own time (s) in its last controls
    lockstep: bool = False     # it answers: a step waits for it when it lags


@dataclass
class _Pace:
    """The world's clock against the wall clock: ``speed`` simulated seconds per wall second from
    (``wall0``, ``sim0``)."""

    speed: float
    wall0: float
    sim0: float

    def ahead(self, sim: float, now: float) -> float:
        """Wall seconds the world at ``sim`` is ahead of its pace (negative: behind)."""
        return (sim - self.sim0) / self.speed - (now - self.wall0)

    def keep_up(self, sim: float, now: float) -> None:
        """A world more than MAX_BEHIND wall seconds behind (a loaded machine) takes up its pace
        from here instead of racing to catch up."""
        if self.ahead(sim, now) < -MAX_BEHIND:
            self.wall0, self.sim0 = now, sim


class Px4HilServer(ServingThread):
    """Serves the PX4 firmware of ``world`` from a background thread (``start``/``stop``).
    ``origin`` is the (lat, lon, AMSL alt) of the world's north = east = 0 on the ground.
    ``lock`` guards the world."""

    def __init__(self, world: World, origin: tuple[float, float, float], *, host: str = "127.0.0.1",
                 ports: Mapping[str, int] | None = None, speed: float = 1.0, rate: int = RATE,
                 reply_timeout: float = REPLY_TIMEOUT, seed: int = 0) -> None:
        self.world = world
        self.origin = origin
        self.host = host
        self.ports = {n: (ports or {}).get(n, hil_port(v.instance)) for n, v in world.vehicles.items()}
        self.speed = speed
        self.dt = 1.0 / rate
        self.reply_timeout = reply_timeout
        self.lock = threading.Lock()
        self.stats = {n: HilStats() for n in world.vehicles}
        self.time = 0.0
        self._rng = random.Random(seed)
        self._per_metre = LocalFrame(*origin).degrees_per_metre()  # WGS84 as sitl.geo has it
        self._links: dict[str, _Link] = {}
        super().__init__("px4-hil")

    # -- life -----------------------------------------------------------------------------------
    def start(self) -> Px4HilServer:
        for name, s in listen_all(socket.SOCK_STREAM, self.host, self.ports, "its PX4 firmware").items():
            link = _Link(name, s, self.stats[name])
            self._links[name] = link
            self._selector.register(s, selectors.EVENT_READ, (link, True))
        self._launch()
        return self

    def stop(self) -> None:
        self._halt()
        for link in self._links.values():
            self._drop(link)
            link.listener.close()
        self._links.clear()
        self._selector.close()

    # -- the loop ---------------------------------------------------------------------------------
    def _run(self) -> None:
        pace = _Pace(self.speed, time.monotonic(), self.time)
        stepped = time.monotonic()
        while not self._stopping.is_set():
            ahead = pace.ahead(self.time, time.monotonic())
            self._serve_io(0.002 if self._lagging() else max(0.0, min(ahead, 0.01)))
            now = time.monotonic()
            if pace.ahead(self.time, now) > 0.0 or not self._answered(now - stepped):
                continue
            pace.keep_up(self.time, now)
            self._step()
            stepped = time.monotonic()

    def _serve_io(self, timeout: float) -> None:
        for key, _ in self._selector.select(timeout=timeout):
            link, listening = key.data
            if listening:
                self._accept(link)
            else:
                self._read(link)

    def _lagging(self) -> list[_Link]:
        return [k for k in self._links.values()
                if k.conn is not None and k.lockstep and k.answered_at < self.time - MAX_LAG - 1e-9]

    def _answered(self, waited: float) -> bool:
        """Whether the next step may run: no firmware lags, or the lagging ones were waited for
        ``reply_timeout`` (then they are not waited for again until they answer)."""
        lagging = self._lagging()
        if lagging and waited < self.reply_timeout:
            return False
        for k in lagging:
            k.stats.waits += 1
            k.lockstep = False
        return True

    def _accept(self, link: _Link) -> None:
        try:
            conn, _ = link.listener.accept()
        except (BlockingIOError, InterruptedError, OSError):
            return
        self._drop(link)
        conn.setblocking(False)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        link.conn = conn
        link.mav = mavlink2.MAVLink(None, 1, 51)
        link.mav.robust_parsing = True
        link.controls, link.answered_at, link.lockstep = (0.0,) * 16, -1.0, False
        link.stats.connects += 1
        self._selector.register(conn, selectors.EVENT_READ, (link, False))

    def _drop(self, link: _Link) -> None:
        if link.conn is not None:
            try:
                self._selector.unregister(link.conn)
            except (KeyError, ValueError):
                pass
            link.conn.close()
            link.conn = None
        link.controls, link.lockstep, link.answered_at = (0.0,) * 16, False, -1.0

    def _read(self, link: _Link) -> None:
        assert link.conn is not None
        try:
            data = link.conn.recv(MAX_READ)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            self._drop(link)  # the firmware is gone: its motors stop
            return
        try:
            msgs = link.mav.parse_buffer(data) or []
        except mavlink2.MAVError:
            link.stats.malformed += len(data)
            return
        for m in msgs:
            if m.get_type() == "HIL_ACTUATOR_CONTROLS":
                c = tuple(float(x) if math.isfinite(x) else 0.0 for x in m.controls)
                link.controls = c if m.mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED else (0.0,) * 16
                link.answered_at, link.lockstep = m.time_usec * 1e-6, True
                link.stats.controls += 1
            elif m.get_type() == "BAD_DATA":
                link.stats.malformed += 1

    def _step(self) -> None:
        with self.lock:
            self.time += self.dt
            for name, link in self._links.items():
                self.world.step_controls(name, link.controls, self.dt)
            out = {name: self._sensors(name) for name, link in self._links.items() if link.conn is not None}
        for name, payload in out.items():
            link = self._links[name]
            link.stats.steps += 1
            assert link.conn is not None
            try:
                link.conn.sendall(payload)
            except (BlockingIOError, InterruptedError):
                pass  # PX4 is not reading: it will get the next step
            except OSError:
                self._drop(link)

    # -- what PX4 is sent ---------------------------------------------------------------------------
    def _sensors(self, name: str) -> bytes:
        link = self._links[name]
        b = self.world.vehicles[name].body
        usec = int(round(self.time * 1e6))
        g = self._rng.gauss
        shake = min(1.0, self.world.ground_speed(name) / VIBRATION_SPEED)
        acc = tuple(a + g(0.0, ACCEL_NOISE + VIBRATION_ACCEL * shake) for a in b.accel_body)
        gyro = tuple(w + g(0.0, GYRO_NOISE + VIBRATION_GYRO * shake) for w in b.gyro)
        mav = link.mav
        sensor = mav.hil_sensor_encode(usec, *acc, *gyro, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                                       0b111111, 0)
        n, e, d = b.position
        lat0, lon0, alt0 = self.origin
        lat, lon, alt = lat0 + n * self._per_metre[0], lon0 + e * self._per_metre[1], alt0 - d
        vn, ve, vd = b.velocity
        milli_g = [int(round(a / GRAVITY * 1000.0)) for a in b.accel_body]
        state = mav.hil_state_quaternion_encode(
            usec, [float(q) for q in b.attitude], *b.gyro, int(round(lat * 1e7)), int(round(lon * 1e7)),
            int(round(alt * 1000.0)), int(round(vn * 100)), int(round(ve * 100)), int(round(vd * 100)),
            0, 0, *(max(-32768, min(32767, a)) for a in milli_g))
        return sensor.pack(mav) + state.pack(mav)
