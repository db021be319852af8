"""The lifecycle every flying command shares, for one team or many: :class:`Session`.

A session owns what a run needs once - the run folder and its write-ahead journal, the mission
clock, the embedded simulated fleet (:func:`fleetctl.run.sim.embedded_fleet`), the links to the
fleet with one route-conflict policy, the exit status, and closing everything in order. The one
class that goes through it, in one order, is :class:`fleetctl.run.crew.Crew`; what flies in it (one
team's flight, or several teams') is chosen by :func:`fleetctl.run.flight.fly` from the mission's
teams. A team of a several-team run is a crew of its own whose session borrows the fleet, the
simulator and the bus of its owner.

The shared vocabulary of a run lives here too: :class:`RunOptions` (the command line's options),
:class:`RunOutcome` and the exit codes.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fleetctl.journal import Journal, run_dir_for, write_summary
from fleetctl.mavlink.fleet import Fleet, connect_fleet
from fleetctl.mavlink.link import LinkError
from fleetctl.mavlink.tlog import TlogWriter
from fleetctl.mavlink.vehicle_clock import VehicleTimeClock
from fleetctl.mission import Mission
from fleetctl.mission.formats import copy_data_files
from fleetctl.mission.links import link_tlogs
from fleetctl.run.context import ExecutionError
from fleetctl.run.kinds import Ev
from fleetctl.run.resume import Resumption
from fleetctl.run.resume_teams import TeamsResumption
from fleetctl.run.sim import mission_uses_sim, sim_fleet_config
from fleetctl.views.view import View

if TYPE_CHECKING:
    from fleetctl.bus.client import FleetBus
    from fleetctl.bus.config import BusConfig
    from sitl import FleetConfig, SimFleet

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_INTERRUPTED = 130
COMMANDS = ("deploy", "collect", "run")
ROUTE_CONFLICT_EVERY = 10.0  # s between route-conflict events from one source


@dataclass
class RunOutcome:
    exit_code: int  # 0 complete, 1 not complete / failed, 130 interrupted
    summary: dict[str, Any]
    run_dir: Path | None = None
    error: str | None = None


@dataclass
class RunOptions:
    """How to fly (the command line's shared options; see :func:`fleetctl.run.flight.execute`)."""

    speedup: float | None = None
    planner: str | None = None
    dwell: float | None = None
    summary_path: str | Path | None = None
    runs_dir: str | Path = "runs"
    run_dir: str | Path | None = None
    view: View | None = None
    connect_timeout: float = 10.0
    endpoints: dict[str, str] | None = None
    on_sim: Callable[[SimFleet], None] | None = None
    on_run_dir: Callable[[Path], None] | None = None
    sim: SimFleet | None = None  # an already running simulated fleet to fly against (tests, benchmarks)
    clock_speedup: float | None = None  # real links to SITL firmware run that much faster: the vehicles' time
    vehicle_clock: VehicleTimeClock | None = None  # that clock, already followed (a team's of a teams run)
    mqtt: BusConfig | None = None  # the bus (default: the mission's mqtt: section)
    resume: Resumption | None = None  # a one-team run to finish
    teams_resume: TeamsResumption | None = None  # a run of several teams to finish
    team: str | None = None  # --team ID: the one team of a several-carrier mission flown (run record)
    require_all: bool = False  # refuse a fleet with a rover that does not answer
    force: bool = False  # fly although another controller seems to be in charge
    confirm: Callable[[list[str]], bool] | None = None  # asked before arming (real vehicles)
    fleet: Fleet | None = None  # an already connected fleet (a team's view of a teams run); not closed
    bus: FleetBus | None = None  # an already started bus (a team's in a teams run): followed, not closed


Emit = Callable[..., object]  # emit(kind, text, vehicle, **data): an event of the crew's


def exit_code(result: str, interrupted: bool) -> int:
    """The process exit status of a run: 130 interrupted, 0 complete, 1 otherwise."""
    return EXIT_INTERRUPTED if interrupted else (EXIT_OK if result == "complete" else EXIT_FAILED)


class Session:
    """What one run of ``command`` over ``mission`` owns (see the module docstring). A session
    given a running simulator, fleet or bus (``opts.sim``/``opts.fleet``/``opts.bus``) uses them
    and leaves closing them to their owner."""

    def __init__(self, mission: Mission, command: str, opts: RunOptions) -> None:
        if command not in COMMANDS:
            raise ValueError(f"unknown command {command!r}")
        self.mission = mission
        self.command = command
        self.opts = opts
        self.sim: SimFleet | None = opts.sim
        self.endpoints = dict(opts.sim.endpoints) if opts.sim is not None else opts.endpoints
        self.uses_sim = opts.sim is None and self.endpoints is None and mission_uses_sim(mission)
        self.sim_config: FleetConfig | None = (sim_fleet_config(mission, command, speedup=opts.speedup)
                                if self.uses_sim else None)
        self.vehicle_clock: VehicleTimeClock | None = None  # the mission clock on the vehicles' time
        self.clock, self.scale = self._clock()
        self.journal = Journal(self._run_dir())
        self.fleet: Fleet | None = None
        self.error: str | None = None
        self.interrupted = False
        self._sim_cm: contextlib.AbstractAsyncContextManager[SimFleet | None] | None = None
        self._conflicts: dict[tuple[str | None, int, str], float] = {}  # route conflicts told -> when
        self._emit: Emit | None = None

    def _run_dir(self) -> Path:
        o = self.opts
        if o.resume is not None:
            d = Path(o.resume.run_dir)
        elif o.teams_resume is not None:
            d = Path(o.teams_resume.run_dir)
        elif o.run_dir is not None:
            d = Path(o.run_dir)
        else:
            d = run_dir_for(self.mission.name, o.runs_dir)
        d.mkdir(parents=True, exist_ok=True)
        return d

    def _clock(self) -> tuple[Callable[[], float], float]:
        """The mission clock: the simulator's time; else, for vehicles that run ``clock_speedup``
        times faster (lockstep SITL firmware), their own time (``time_boot_ms``,
        :class:`~fleetctl.mavlink.vehicle_clock.VehicleTimeClock`: the wall clock times
        ``clock_speedup`` until they report, and where they are silent); else the wall clock."""
        if self.sim is not None:
            sim = self.sim
            return (lambda: float(sim.sim_time)), float(sim.speedup)
        if self.sim_config is not None:
            return time.monotonic, float(self.sim_config.speedup)  # until the simulator runs
        if self.opts.clock_speedup is not None:
            scale = float(self.opts.clock_speedup)
            self.vehicle_clock = self.opts.vehicle_clock or VehicleTimeClock(scale)
            return self.vehicle_clock, scale
        return time.monotonic, 1.0

    # -- the way in ------------------------------------------------------------------------------
    def open_records(self) -> None:
        """Tell ``on_run_dir`` where the records go and start the journal's writer."""
        if self.opts.on_run_dir is not None:
            self.opts.on_run_dir(self.journal.dir)
        self.journal.start()

    async def begin_records(self, **extra: Any) -> None:
        """A new run's first records: the mission file and the data files it names copied into the
        run folder (for resume), then the ``run`` record (``extra``: more of its fields). A resumed
        run's journal goes on instead."""
        if self.opts.resume is not None or self.opts.teams_resume is not None:
            return
        m, j = self.mission, self.journal
        if m.path is not None:
            with contextlib.suppress(OSError):
                await asyncio.to_thread(j.save_mission, m.path)
                await asyncio.to_thread(copy_data_files, m, j.dir)  # tasks/obstacles {file}: for resume
        if self.opts.team is not None:  # resume flies this team again
            extra["team"] = self.opts.team
        await j.commit(Ev.RUN, mission=m.name, command=self.command, file=str(m.path or ""),
                       sim=self.uses_sim, speedup=self.scale, planner=self.opts.planner,
                       dwell=self.opts.dwell, unix_t0=time.time(), **extra)

    async def start_sim(self) -> None:
        """Start the embedded simulated fleet (``connection: sim``): the mission clock becomes its
        simulated time and the fleet's links its endpoints."""
        if not self.uses_sim:
            return
        from fleetctl.run.sim import embedded_fleet

        self._sim_cm = embedded_fleet(self.mission, config=self.sim_config)
        self.sim = sim = await self._sim_cm.__aenter__()
        assert sim is not None  # started from its configuration whatever the connections say
        self.clock = lambda: float(sim.sim_time)
        self.endpoints = dict(sim.endpoints)
        self.journal.write(Ev.SIM_STARTED, endpoints=self.endpoints, speedup=self.scale)
        if self.opts.on_sim is not None:
            self.opts.on_sim(sim)

    def pin_scenario_batteries(self, pinned: bool) -> None:
        """A collection on a simulated fleet: each rover of the ``collection:`` section has its
        ``range`` left (``range = (remaining - reserve) x endurance_range``) when the collection
        starts; ``pinned``, the simulator holds it there (while the fleet connects and the first
        plan is made), else it drains as usual."""
        if self.sim is None or self.command != "collect" or not self.mission.collection:
            return
        rp = self.mission.rovers
        for cr in self.mission.collection:
            level = min(1.0, rp.reserve + cr.range / rp.endurance_range)
            self.sim.pin_battery(cr.id, level if pinned else None)

    async def connect(self, emit: Emit) -> Fleet:
        """The fleet: the one given, or every vehicle of the mission on its links, with the route
        conflict policy (:meth:`route_conflict`) telling conflicts through ``emit``."""
        self._emit = emit
        if self.opts.fleet is not None:
            self.fleet = self.opts.fleet
            self._mission_silences(self.fleet)
            return self.fleet
        try:
            fleet = await connect_fleet(self.mission, self.endpoints, timeout=self.opts.connect_timeout,
                                        tap=self._link_tlogs(), require_all=False)
        except LinkError as exc:
            raise ExecutionError(f"cannot open the link: {exc}") from None
        fleet.on_route_conflict(self.route_conflict)
        self._mission_silences(fleet)
        self.fleet = fleet
        return fleet

    def _link_tlogs(self) -> dict[str, TlogWriter]:
        """Link key -> the run folder's ``.tlog`` of that link (``traffic.tlog`` for the first)."""
        return {key: self.journal.link_tlog(name) for key, name in link_tlogs(self.mission).items()}

    def _mission_silences(self, fleet: Fleet) -> None:
        """A vehicle is lost after ``links.heartbeat_timeout`` of mission time (the run's clock);
        a clock on the vehicles' time hears each vehicle's."""
        if self.vehicle_clock is not None and self.vehicle_clock.reference is None:
            self.vehicle_clock.reference = fleet.carrier.name  # the carrier's time, while it is heard
        for v in fleet.vehicles.values():
            if self.vehicle_clock is not None:
                v.follow_time(self.vehicle_clock.observe)
            v.use_clock(self.clock, self.scale)

    def route_conflict(self, vid: str | None, sysid: int, old: Any, new: Any) -> None:
        """A known system id heard from a new address: told once per source and
        :data:`ROUTE_CONFLICT_EVERY` seconds, never acted on (the first address stays)."""
        key, now = (vid, sysid, str(new)), time.monotonic()  # a sysid may repeat on another link
        if now - self._conflicts.get(key, -1e9) < ROUTE_CONFLICT_EVERY or self._emit is None:
            return
        self._conflicts[key] = now
        self._emit(Ev.ROUTE_CONFLICT, f"{vid or sysid}: a message with its system id came from {new} "
                   f"while it is heard at {old}: ignored (spoofing, or a second radio path)", vid,
                   sysid=sysid, old=str(old), new=str(new))

    # -- the flight ------------------------------------------------------------------------------
    def was_interrupted(self) -> None:
        """Called in the ``except CancelledError`` of the crew's run: the run goes on to write its
        records (the cancellation is absorbed) and ends with :data:`EXIT_INTERRUPTED`."""
        task = asyncio.current_task()
        if task is not None:
            task.uncancel()
        self.interrupted = True

    def outcome(self, summary: dict[str, Any]) -> RunOutcome:
        code = exit_code(summary["result"], self.interrupted)
        return RunOutcome(code, summary, self.journal.dir, self.error)

    # -- the way out -----------------------------------------------------------------------------
    def write_summary(self, summary: dict[str, Any]) -> None:
        self.journal.write(Ev.SUMMARY, **summary)
        write_summary(summary, self.journal.summary_path, self.opts.summary_path)

    async def close(self, close_bus: Callable[[], Awaitable[object]] | None = None) -> None:
        """Close in order: the view, the fleet (unless borrowed), the bus (``close_bus()``), the
        journal, the simulator (unless borrowed)."""
        if self.opts.view is not None:
            with contextlib.suppress(Exception):
                await self.opts.view.stop()
        if self.fleet is not None and self.vehicle_clock is not None and self.opts.vehicle_clock is None:
            for v in self.fleet.vehicles.values():  # a borrowed fleet outlives the session
                v.unfollow_time(self.vehicle_clock.observe)
        if self.fleet is not None and self.opts.fleet is None:
            with contextlib.suppress(Exception):
                await self.fleet.close()
        if close_bus is not None:
            with contextlib.suppress(Exception):
                await close_bus()
        await self.journal.aclose()
        if self._sim_cm is not None:
            with contextlib.suppress(Exception):
                await self._sim_cm.__aexit__(None, None, None)


class OnSession:
    """What a crew and its flight (:mod:`fleetctl.run.crew`) read from their :attr:`session`: the
    mission clock and its scale, the simulator, the endpoints, the
    error and whether it was interrupted."""

    session: Session

    @property
    def clock(self) -> Callable[[], float]:
        return self.session.clock

    @property
    def scale(self) -> float:
        return self.session.scale

    @property
    def sim(self) -> SimFleet | None:
        return self.session.sim

    @property
    def endpoints(self) -> dict[str, str] | None:
        return self.session.endpoints

    @property
    def error(self) -> str | None:
        return self.session.error

    @error.setter
    def error(self, value: str | None) -> None:
        self.session.error = value

    @property
    def interrupted(self) -> bool:
        return self.session.interrupted


__all__ = [
    "COMMANDS",
    "EXIT_FAILED",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "OnSession",
    "RunOptions",
    "RunOutcome",
    "Session",
    "exit_code",
]
