"""The controller's state model: what the dashboard and the journal read.

:class:`FleetState` holds one :class:`VehicleState` per vehicle (role, controller state, ENU
position, altitude, speed, battery, range, link age), the mission phase, the stop being served
(k of N), planned vs elapsed time and the latest :class:`Event` s. The executor writes the
controller-side fields (``state``, ``task``, phase, stop) and raises events; :meth:`FleetState.refresh`
copies the telemetry of the live :class:`fleetctl.mavlink.fleet.Fleet` into it. Listeners (journal,
headless log) get every event as it happens.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from fleetctl.run.energy import range_from_percent
from fleetctl.run.kinds import Phase, VehicleStatus

if TYPE_CHECKING:
    from fleetctl.mavlink.fleet import Fleet
    from fleetctl.mission import Mission

log = logging.getLogger(__name__)

@dataclass
class VehicleState:
    id: str
    role: str  # "carrier" | "rover"
    sysid: int
    url: str = ""
    state: str = VehicleStatus.UNKNOWN
    task: str | None = None
    enu: tuple[float, float, float] | None = None
    alt: float | None = None  # height above home (m)
    speed: float | None = None  # ground speed (m/s)
    battery_pct: float | None = None
    range_m: float | None = None  # from fleetctl.run.energy (rovers)
    link_age: float | None = None  # s since last message
    connected: bool = False
    lost: bool = False
    armed: bool = False
    mode: str | None = None
    on_ground: bool | None = None
    latlon: tuple[float, float] | None = None  # WGS84 degrees (the view's --latlon)
    telemetry_at: float | None = None  # time.monotonic() of the last position or landed state
    state_at: float | None = None  # time.monotonic() when ``state`` was last set


@dataclass(frozen=True)
class Event:
    elapsed: float  # s since the run started (wall clock)
    kind: str
    vehicle: str | None
    text: str
    data: dict[str, Any] = field(default_factory=dict)
    time: float = 0.0  # Unix time
    mission_time: float | None = None  # mission s since the run started (T+; FleetState.mission_time)


EventListener = Callable[[Event], None]


class FleetState:
    """Everything the operator sees about a run, updated by the executor and from telemetry."""

    def __init__(self, mission: Mission, urls: dict[str, str] | None = None, max_events: int = 12) -> None:
        self.mission_name = mission.name
        self.reserve = mission.rovers.reserve
        self.endurance_range = mission.rovers.endurance_range
        urls = urls or {}
        self.vehicles: dict[str, VehicleState] = {
            mission.carrier.id: VehicleState(mission.carrier.id, "carrier", mission.carrier.sysid,
                                             urls.get(mission.carrier.id, ""))}
        for u in mission.rovers.units:
            self.vehicles[u.id] = VehicleState(u.id, "rover", u.sysid, urls.get(u.id, ""))
        self.carrier_id = mission.carrier.id
        self.deck_height = mission.carrier.deck_height
        self.phase: str = Phase.CONNECT
        self.stop_index = 0  # 1-based stop being driven to / served; 0 before the first
        self.stop_count = 0
        self.planned: float | None = None  # planned makespan of the current phase (mission seconds)
        self.eta: float | None = None  # predicted makespan from the live fleet (mission s of the phase)
        self.phase_started: float | None = None  # mission clock at the phase start
        self._clock: Callable[[], float] = time.monotonic
        self._clock_t0 = self._clock()  # the clock's reading at T+0 (the run's start)
        self.tasks: dict[str, tuple[float, float, float]] = {t.id: t.position for t in mission.tasks}
        self.rover_motion: Any = mission.rovers.motion()  # the time model's rover motion (None: unknown)
        self.plan: dict[str, Any] | None = None  # the plan being flown (fleetctl.plan/1 JSON)
        self.plan_started: float | None = None  # mission clock at the plan's t = 0
        self.started = time.monotonic()
        self.events: deque[Event] = deque(maxlen=max_events)
        self._listeners: list[EventListener] = []
        self.replans = 0  # replans so far (fleetctl.run.executor)
        self.last_replan: str | None = None  # text of the latest replan event
        self.link: dict[str, int] = {}  # what the links refused (Fleet.link_rejections)
        self.operation: Callable[[], OperationProgress] | None = None  # a long operation's progress (views)
        self.signing = False

    @property
    def link_line(self) -> str:
        """The link's security state for the view ('' when unsigned and nothing was refused)."""
        refused = {k: n for k, n in self.link.items() if n}
        if not self.signing and not refused:
            return ""
        head = "signed" if self.signing else "unsigned"
        return head + "".join(f" · {k.replace('_', ' ')} {n}" for k, n in refused.items())

    @property
    def link_style(self) -> str:
        return "yellow" if any(self.link.values()) else "green"

    # -- events ---------------------------------------------------------------------------------
    def add_listener(self, listener: EventListener) -> Callable[[], None]:
        self._listeners.append(listener)
        return lambda: self._listeners.remove(listener) if listener in self._listeners else None

    def event(self, kind: str, text: str, vehicle: str | None = None, **data: Any) -> Event:
        """Record an event and tell every listener."""
        ev = Event(time.monotonic() - self.started, kind, vehicle, text, data, time.time(), self.mission_time)
        self.events.append(ev)
        log.info("%s", text)
        for listener in list(self._listeners):
            try:
                listener(ev)
            except Exception:  # noqa: BLE001 - a broken listener must not stop the mission
                log.exception("event listener failed")
        return ev

    # -- the one time base: mission seconds since the run started ------------------------------
    @property
    def mission_clock(self) -> Callable[[], float]:
        return self._clock

    @mission_clock.setter
    def mission_clock(self, clock: Callable[[], float]) -> None:
        """A new clock (e.g. the simulator's once it runs) keeps T+ continuous."""
        t = self.mission_time
        self._clock = clock
        self._clock_t0 = clock() - t

    def count_from(self, t0: float) -> None:
        """T+ counts from mission clock ``t0`` (a team's run: from the start of the run of every team)."""
        self._clock_t0 = t0

    @property
    def mission_time(self) -> float:
        """Mission seconds since the run started (``T+``): simulated seconds on the embedded sim."""
        return self._clock() - self._clock_t0

    def set_plan(self, plan: dict[str, Any], started: float | None = None) -> None:
        """The plan now flown (its JSON) and the mission clock at its t = 0 (None: not yet)."""
        self.plan = plan
        self.plan_started = started

    # -- phase / stops --------------------------------------------------------------------------
    def set_phase(self, phase: str, planned: float | None = None, stops: int = 0) -> None:
        self.phase = phase
        self.planned = planned
        self.eta = planned
        self.stop_count = stops
        self.stop_index = 0
        self.phase_started = self.mission_clock()

    @property
    def elapsed(self) -> float:
        """Mission seconds since the phase started (simulated seconds on the embedded sim)."""
        if self.phase_started is None:
            return 0.0
        return max(0.0, self.mission_clock() - self.phase_started)

    @property
    def wall_elapsed(self) -> float:
        return time.monotonic() - self.started

    def set_state(self, vid: str, state: str, task: str | None = None) -> None:
        v = self.vehicles.get(vid)
        if v is None:
            return
        v.state = state
        v.state_at = time.monotonic()
        if task is not None:
            v.task = task

    def rovers(self) -> list[VehicleState]:
        return [v for v in self.vehicles.values() if v.role == "rover"]

    # -- telemetry ---------------------------------------------------------------------------------
    def refresh(self, fleet: Fleet) -> None:
        """Copy the live telemetry of ``fleet`` (cheap; called a few times a second)."""
        self.link = fleet.link_rejections()
        self.signing = fleet.signing
        carrier = fleet.vehicles.get(fleet.carrier_id)
        cpos = carrier.enu if carrier is not None else None
        for vid, v in fleet.vehicles.items():
            s = self.vehicles.get(vid)
            if s is None:
                continue
            s.connected = v.connected
            s.lost = v.lost
            s.armed = v.armed
            s.mode = v.mode
            s.enu = v.enu
            s.alt = v.height
            s.speed = v.ground_speed
            s.battery_pct = v.battery_pct
            s.link_age = v.last_heard_age
            s.on_ground = v.on_ground
            s.telemetry_at = v.telemetry_at
            s.latlon = (v.position[0], v.position[1]) if v.position is not None else None
            if s.role == "rover":
                try:
                    s.range_m = range_from_percent(v.battery_pct, self.reserve, self.endurance_range)
                except ValueError:
                    s.range_m = None
                if (s.state == VehicleStatus.UNKNOWN and v.connected
                        and on_deck(v.enu, cpos, v.on_ground, v.ground_speed, v.height, self.deck_height)):
                    s.state = VehicleStatus.ON_DECK

    def snapshot(self) -> dict[str, Any]:
        """Plain dict of the whole state (for the journal / tests)."""
        return {
            "phase": self.phase, "stop": self.stop_index, "stops": self.stop_count, "planned": self.planned,
            "eta": self.eta,
            "elapsed": self.elapsed, "replans": self.replans, "last_replan": self.last_replan,
            **({"operation": dataclasses.asdict(self.operation())} if self.operation is not None else {}),
            "vehicles": {vid: {"state": v.state, "task": v.task, "enu": v.enu, "battery_pct": v.battery_pct,
                               "lost": v.lost} for vid, v in self.vehicles.items()},
        }


@dataclass(frozen=True)
class SortieShown:
    """A sortie out (launched, not back): its index, rover, state (flying or returning) and tasks."""

    index: int
    rover: str
    status: str
    tasks: tuple[str, ...]


@dataclass(frozen=True)
class SortieAhead:
    """A sortie of the plan flown that has not taken off yet: its index, rover and tasks, its launch
    and pick-up stops (ENU east, north; no pick-up: it ends on the ground) and the mission seconds
    until its planned take-off (moved by the operation's delay so far)."""

    index: int
    rover: str
    tasks: tuple[str, ...]
    launch: tuple[float, float]
    pickup: tuple[float, float] | None
    takeoff_in: float


@dataclass(frozen=True)
class OperationProgress:
    """A long operation as the views show it: its sorties, each task's work and the end it heads for."""

    sorties_out: int  # launched, not back yet
    sorties_back: int
    sorties_planned: int  # every sortie of the plans flown so far
    tasks: dict[str, tuple[float, float, str | None, bool]]  # task -> (s worked, duration s, rover, done)
    eta: float | None  # mission s of the phase: the plan's end moved by the delay so far
    out: tuple[SortieShown, ...] = ()  # the sorties out now
    ahead: tuple[SortieAhead, ...] = ()  # the plan's sorties not launched yet, the next first

    @property
    def done(self) -> int:
        return sum(1 for *_w, done in self.tasks.values() if done)

    def working(self) -> list[tuple[str, float, float, str | None]]:
        """Tasks being worked now: (task, s worked, duration s, rover)."""
        return [(t, w, d, r) for t, (w, d, r, done) in self.tasks.items() if w > 0.0 and not done]


DECK_RADIUS = 1.5  # m: a landed rover this close (horizontally) to the carrier is on its deck
DECK_HEIGHT = 0.15  # m: a rover this low above the carrier, at rest, is down on the deck
LANDED_HEIGHT = 1.0  # m: height slack when the autopilot itself reports ON_GROUND (GPS altitude noise)


def on_deck(pos: tuple[float, float, float] | None, carrier: tuple[float, float, float] | None,
            on_ground: bool | None, speed: float | None = None, height: float | None = None,
            deck: float = 0.0) -> bool:
    """A rover is on the carrier's deck when it is within :data:`DECK_RADIUS` (horizontal) of the
    carrier and either reports ON_GROUND within :data:`LANDED_HEIGHT` of the carrier's altitude or
    of its own home (``height``: metres above its home, which a rover sets on the deck) - a ground
    vehicle's altitude drifts by metres: PX4 SITL's rover carrier reads 2 m low within a minute,
    3 m after two flights, while its rovers stand next to it -, or is at rest within
    :data:`DECK_HEIGHT` of it (the landed state comes at ~1 Hz, positions much faster; ArduCopter
    reports its landing 1.6 s after the touch-down, when its land detector has seen it). ``deck``:
    the deck's height above the carrier's reported altitude (``carrier.deck_height``)."""
    if pos is None or carrier is None:
        return False
    if math.hypot(pos[0] - carrier[0], pos[1] - carrier[1]) > DECK_RADIUS:
        return False
    dz = pos[2] - carrier[2] - deck
    if on_ground is True and (dz <= LANDED_HEIGHT or (height is not None and height <= LANDED_HEIGHT)):
        return True
    return dz <= DECK_HEIGHT and (speed is None or speed < 0.2)


__all__ = ["DECK_HEIGHT", "DECK_RADIUS", "LANDED_HEIGHT", "Event", "FleetState", "OperationProgress",
           "SortieAhead", "SortieShown", "VehicleState", "on_deck"]
