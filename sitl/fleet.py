"""The simulated fleet: world + autopilots + UDP endpoints on one asyncio loop.

One task ticks at ``tick_hz`` wall-clock: it advances the world in fixed steps of ``step``
simulated seconds up to ``speedup`` x the elapsed wall time, runs every autopilot after each
step, then sends the telemetry that is due. Streams are scheduled on :meth:`SimFleet.stream_time`:
their rates hold per simulated second (a position at 10 Hz is ten per simulated second at any
speed-up, up to one per tick), and per wall second when the simulation runs slower than real time.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import signal
import time
from collections.abc import Awaitable, Callable
from typing import Any

from .config import FleetConfig
from .endpoint import LinkSpec, UdpEndpoint, parse_connection
from .faults import Fault, FaultBook
from .flavour import Flavour
from .geo import LocalFrame
from .vehicle import SimVehicle
from .world import AnyBody, Rover, World

log = logging.getLogger(__name__)

MAX_BEHIND_S = 0.25  # wall seconds of simulated time one tick may catch up at most


class SimFleet:
    """A simulated marsupial fleet speaking MAVLink 2 over UDP.

    ``async with SimFleet(config) as fleet:`` opens the endpoints and starts the simulation;
    ``fleet.endpoints`` maps vehicle id -> the URL the controller uses.
    """

    def __init__(self, config: FleetConfig) -> None:
        self.config = config
        self.world = World(config.carrier, config.rovers, config.more_carriers)
        self.frame = LocalFrame(*config.origin)
        self.faults = FaultBook(config.faults)
        self._stream_t = 0.0  # the streams' clock (stream_time)
        self._stream_wall = time.monotonic()  # wall time and simulated time it was last advanced at
        self._stream_sim = 0.0
        self.vehicles: dict[str, SimVehicle] = {}
        for spec in config.vehicles:
            body = self.world.body(spec.id)
            ground = spec.role == "carrier" and spec.frame == "ground"
            flavour = Flavour(config.autopilot, ground)
            v = SimVehicle(spec, body, flavour, self.frame, self, self.faults, config.position_hz)
            if isinstance(body, Rover):
                body.land_travel = flavour.land_travel()
                body.drain_factor = self._drain_getter(spec.id)
                body.land_drift = self._drift_getter(spec.id)
            if config.signing_key is not None:
                v.set_signing_key(config.signing_key)
            self.vehicles[spec.id] = v
        self._links: list[tuple[LinkSpec, list[str]]] = self._group_links()
        self._endpoints: list[UdpEndpoint] = []
        self._endpoint_of: dict[str, UdpEndpoint] = {}
        self._task: asyncio.Task[None] | None = None
        self._speedup = config.speedup
        self._wall0 = time.monotonic()
        self._steps0 = 0
        self.steps = 0
        self.ticks = 0
        self.errors = 0
        self.last_error: BaseException | None = None

    def _drain_getter(self, vid: str) -> Callable[[], float]:
        return lambda: self.faults.drain_factor(vid, self.world.time)

    def _drift_getter(self, vid: str) -> Callable[[], float]:
        return lambda: self.faults.land_drift(vid, self.world.time)

    def _group_links(self) -> list[tuple[LinkSpec, list[str]]]:
        """One endpoint per link of the configuration (:meth:`FleetConfig.link_groups`)."""
        return [(parse_connection("sim" if key.startswith("sim#") else key), ids)
                for key, ids in self.config.link_groups().items()]

    # -- clock (the vehicles' view of time) ---------------------------------------------------
    @property
    def sim_time(self) -> float:
        """Simulated seconds since the start."""
        return self.world.time

    def wall(self) -> float:
        return time.monotonic()

    def stream_time(self) -> float:
        """The telemetry streams' clock: it advances by the simulated time of each tick, or by the
        wall time when that is longer (a simulation slower than real time still sends its
        heartbeats every wall second)."""
        return self._stream_t

    def _advance_stream_time(self, now: float) -> None:
        sim = self.world.time
        self._stream_t += max(now - self._stream_wall, sim - self._stream_sim, 0.0)
        self._stream_wall, self._stream_sim = now, sim

    @property
    def speedup(self) -> float:
        return self._speedup

    def set_speedup(self, speedup: float) -> None:
        if not (math.isfinite(speedup) and speedup > 0):
            raise ValueError(f"speedup must be > 0, got {speedup}")
        self._wall0, self._steps0, self._speedup = time.monotonic(), self.steps, float(speedup)

    # -- lifecycle -----------------------------------------------------------------------------
    async def start(self) -> None:
        """Open every endpoint and start the simulation task."""
        if self._task is not None:
            return
        try:
            for spec, ids in self._links:
                ep = UdpEndpoint(spec, self, self.faults, self.config.seed, name=ids[0])
                for vid in ids:
                    ep.attach(self.vehicles[vid])
                    self._endpoint_of[vid] = ep
                await ep.open()
                self._endpoints.append(ep)
        except BaseException:
            for ep in self._endpoints:
                ep.close()
            self._endpoints.clear()
            raise
        self._wall0, self._steps0 = time.monotonic(), self.steps
        self._stream_wall = self._wall0
        self._task = asyncio.get_running_loop().create_task(self._run(), name=f"sitl-{self.config.name}")
        for v in self.vehicles.values():
            v.statustext("Simulated autopilot ready")
        log.info("simulated fleet %s: %s", self.config.name, self.endpoints)

    async def stop(self) -> None:
        """Stop the simulation and close every endpoint."""
        task, self._task = self._task, None
        if task is not None:
            task.cancel()  # (asyncio.wait: a cancel of the caller meanwhile is not swallowed)
            await asyncio.wait({task}, timeout=2.0)
        for ep in self._endpoints:
            ep.flush()
            ep.close()
        self._endpoints.clear()

    async def __aenter__(self) -> SimFleet:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    @property
    def running(self) -> bool:
        return self._task is not None and not self._task.done()

    # -- what tests and the CLI read -------------------------------------------------------------
    @property
    def endpoints(self) -> dict[str, str]:
        """vehicle id -> the URL the controller uses to reach it (after ``start``)."""
        return {vid: ep.url for vid, ep in self._endpoint_of.items()}

    def vehicle(self, vehicle_id: str) -> SimVehicle:
        return self.vehicles[vehicle_id]

    def body(self, vehicle_id: str) -> AnyBody:
        return self.world.body(vehicle_id)

    def rover(self, vehicle_id: str) -> Rover:
        return self.world.rovers[vehicle_id]

    def pin_battery(self, vehicle_id: str, level: float | None) -> None:
        """Hold a rover's battery at ``level`` (0..1) while a scenario is being set up (it uses none
        in the air meanwhile); ``None`` lets it drain again from where it is."""
        r = self.world.rovers[vehicle_id]
        if level is not None:
            r.battery = min(max(float(level), 0.0), 1.0)
        r.battery_pinned = level is not None

    def link_stats(self, vehicle_id: str | None = None) -> dict[str, int]:
        """Counters of one vehicle's endpoint, or summed over all endpoints."""
        eps = [self._endpoint_of[vehicle_id]] if vehicle_id else self._endpoints
        total: dict[str, int] = {}
        for ep in eps:
            for k, v in ep.stats.as_dict().items():
                total[k] = total.get(k, 0) + v
        return total

    def signing_rejections(self, vehicle_id: str | None = None) -> dict[str, int]:
        """Messages one vehicle (or every vehicle, summed) dropped for signing: unsigned,
        bad_signature, replay."""
        vs = [self.vehicles[vehicle_id]] if vehicle_id else list(self.vehicles.values())
        total = {"unsigned": 0, "bad_signature": 0, "replay": 0}
        for v in vs:
            for k, n in v.signing.rejected.items():
                total[k] += n
        return total

    def snapshot(self) -> dict[str, dict[str, Any]]:
        """Plain-data state of every vehicle (position ENU, battery, loaded, armed, mode, ...)."""
        out: dict[str, dict[str, Any]] = {}
        for vid, v in self.vehicles.items():
            b = v.body
            out[vid] = {
                "position": b.position,
                "armed": v.armed,
                "mode": v.mode.value,
                "battery": v.battery_fraction(),
                "loaded": isinstance(b, Rover) and b.loaded,
                "on_ground": not isinstance(b, Rover) or b.on_ground,
                "mission_current": v.current,
                "mission_finished": v.finished,
            }
        return out

    # -- faults ----------------------------------------------------------------------------------
    def inject(self, fault: Fault) -> None:
        """Add a fault (times are simulated seconds; ``at`` defaults to 0 = active now)."""
        if fault.vehicle is not None and fault.vehicle not in self.vehicles:
            raise KeyError(f"no vehicle {fault.vehicle!r} in the fleet")
        self.faults.add(fault)

    def clear_faults(self, kind: str | None = None, vehicle: str | None = None) -> int:
        return self.faults.remove(kind, vehicle)

    def set_packet_loss(self, rate: float, vehicle: str | None = None) -> None:
        """Replace the packet loss of ``vehicle`` (None = the fleet-wide one) from now on."""
        self.faults.remove("packet_loss", vehicle)
        if rate > 0:
            self.inject(Fault("packet_loss", vehicle=vehicle, rate=rate))

    def set_latency(self, seconds: float, vehicle: str | None = None) -> None:
        self.faults.remove("latency", vehicle)
        if seconds > 0:
            self.inject(Fault("latency", vehicle=vehicle, seconds=seconds))

    def dropout(self, vehicle: str, duration: float | None = None) -> None:
        """Make ``vehicle`` silent and deaf now, for ``duration`` simulated seconds (None = for good)."""
        t = self.sim_time
        self.inject(Fault("dropout", vehicle=vehicle, at=t, until=None if duration is None else t + duration))

    # -- waiting helpers (tests, scripts) -------------------------------------------------------
    async def wait_for(self, predicate: Callable[[], bool], timeout: float) -> None:
        """Wait (wall seconds) until ``predicate()`` holds, checked every tick; TimeoutError otherwise."""
        async with asyncio.timeout(timeout):
            while not predicate():
                if self._task is not None and self._task.done():
                    raise RuntimeError("the simulation task has stopped")
                await asyncio.sleep(1.0 / self.config.tick_hz)

    async def wait_sim_time(self, t: float, timeout: float) -> None:
        await self.wait_for(lambda: self.sim_time >= t, timeout)

    # -- the simulation loop -------------------------------------------------------------------------
    async def _run(self) -> None:
        period = 1.0 / self.config.tick_hz
        next_t = time.monotonic()
        while True:
            now = time.monotonic()
            try:
                self.tick(now)
            except Exception as exc:  # noqa: BLE001 - keep serving, but make it visible
                self.errors += 1
                self.last_error = exc
                log.exception("simulation tick failed")
            next_t += period
            delay = next_t - time.monotonic()
            if delay < -period:
                next_t = time.monotonic()
                delay = 0.0
            await asyncio.sleep(max(delay, 0.0))

    def tick(self, now: float) -> None:
        """Advance the world to wall time ``now`` and send what is due (one loop iteration)."""
        self.ticks += 1
        cfg = self.config
        dt = cfg.step
        target = self._steps0 + int((now - self._wall0) * self._speedup / dt + 1e-9)
        cap = self.steps + max(1, int(MAX_BEHIND_S * self._speedup / dt))
        end = min(target, cap)
        vehicles = list(self.vehicles.values())
        world = self.world
        while self.steps < end:
            world.step(dt)
            self.steps += 1
            world.time = self.steps * dt
            t = world.time
            for v in vehicles:
                v.update(t)
        self._advance_stream_time(now)
        st = self._stream_t
        due = [v for v in vehicles if st >= v.next_due and v.geodetic_stale()]
        if len(due) > 1:
            positions = [v.body.position for v in due]
            for v, geo in zip(due, self.frame.to_geodetic_many(positions), strict=True):
                v.set_geodetic(geo, v.body.pos_key())
        for v in vehicles:
            v.service(now, st)

    @property
    def behind(self) -> float:
        """Simulated seconds the simulation is behind speedup x wall time (0 when it keeps up)."""
        target = self._steps0 + (time.monotonic() - self._wall0) * self._speedup / self.config.step
        return max(0.0, (target - self.steps) * self.config.step)


async def run_forever(
    config: FleetConfig,
    on_ready: Callable[[SimFleet], Awaitable[None] | None] | None = None,
    stop: asyncio.Event | None = None,
) -> None:
    """Serve ``config`` until ``stop`` is set, SIGTERM/SIGINT arrives or the task is cancelled."""
    stop = stop or asyncio.Event()
    loop = asyncio.get_running_loop()
    installed = []
    for sig in (signal.SIGTERM, signal.SIGINT):
        # no Unix signals on this platform (NotImplementedError) or not the main thread (RuntimeError,
        # ValueError): the fleet then stops through ``stop`` or cancellation only, as documented
        with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
            loop.add_signal_handler(sig, stop.set)
            installed.append(sig)
    try:
        async with SimFleet(config) as fleet:
            if on_ready is not None:
                res = on_ready(fleet)
                if asyncio.iscoroutine(res):
                    await res
            await stop.wait()
    finally:
        for sig in installed:
            loop.remove_signal_handler(sig)


def serve(config: FleetConfig, on_ready: Callable[[SimFleet], Awaitable[None] | None] | None = None) -> None:
    """Blocking: serve the fleet until Ctrl-C / SIGTERM."""
    with contextlib.suppress(KeyboardInterrupt):
        asyncio.run(run_forever(config, on_ready))
