"""The typed mission: what a validated mission file becomes (:mod:`fleetctl.mission.loader` builds
it), and the planning problems it gives the planners."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fleetctl.geo import Origin, compass_to_math
from fleetctl.mission.flight import GROUND_HEIGHT, MEET_HEIGHT, TAKEOFF_HEIGHT
from planners.core.problem import (
    CarrierSpec,
    CollectProblem,
    CollectRover,
    DeployProblem,
    Motion,
    RoadmapParams,
    Task,
)
from planners.operations.problem import OperationProblem, OpTask

Vec2 = tuple[float, float]
Vec3 = tuple[float, float, float]

FAULT_KINDS = ("dropout", "packet_loss", "latency", "battery_drain", "refuse_arm", "reject_mission",
               "no_gps", "unhealthy", "low_battery", "drive_off", "land_drift")
FAILSAFE_ACTIONS = ("keep", "hold", "land", "rtl")  # links.failsafe
FENCE_ACTIONS = ("report", "hold", "rtl", "land")  # geofence.action


class MissionError(Exception):
    """A mission file the controller cannot use; the message says where and what to change."""


# --------------------------------------------------------------------------- typed configuration


@dataclass(frozen=True)
class CarrierConfig:
    id: str
    connection: str
    sysid: int
    position: Vec2
    heading_deg: float
    max_speed: float
    accel: float | None
    turn_rate: float | None
    unload_time: float
    load_time: float
    firmware_speeds: str = "keep"  # set | keep (docs/autopilots.md)
    swap_time: float = 0.0  # s to swap one rover's battery on the deck (a long operation)
    deck_height: float = 0.0  # m of the deck above the carrier's reported altitude (on_deck)

    def spec(self) -> CarrierSpec:
        return CarrierSpec(self.max_speed, self.accel, self.turn_rate, self.unload_time, self.load_time)


@dataclass(frozen=True)
class TeamConfig:
    """One carrier and the ids of the rovers on its deck (``carriers:``; docs/teams.md)."""

    carrier: CarrierConfig
    rovers: tuple[str, ...]


@dataclass(frozen=True)
class TaskWork:
    """The work at one task (``tasks[].duration``, ``tasks[].work``): seconds of work, and whether
    the rover works landed (no battery burnt) or hovering."""

    duration: float
    ground: bool = False


@dataclass(frozen=True)
class RoverUnit:
    id: str
    sysid: int
    connection: str | None  # None = shares the carrier's link


@dataclass(frozen=True)
class EnergyConfig:
    initial: float
    task: float
    rho: float  # metres of flight per unit of energy


@dataclass(frozen=True)
class RoversConfig:
    max_speed: float
    accel: float | None
    deploy_range: float  # given, or derived from ``energy``
    endurance_range: float
    reserve: float
    units: tuple[RoverUnit, ...]  # deck order
    energy: EnergyConfig | None = None
    climb_rate: float = 1.0  # m/s (the loader defaults it to max_speed)
    land_speed: float = 1.0  # m/s (the loader defaults it to climb_rate)
    takeoff_time: float = 0.0  # s, time model: start command -> clear of the deck (fleetctl.mission.flight)
    land_time: float = 0.0  # s, time model: above the stop with the carrier there -> loaded
    firmware_speeds: str = "keep"  # set | keep: the mission's speeds written to the autopilots
    handling_given: tuple[bool, bool] = (True, True)  # takeoff_time, land_time given in the file
    work: str = "hover"  # how a rover works at a task unless the task says: hover | ground

    @property
    def ids(self) -> tuple[str, ...]:
        return tuple(u.id for u in self.units)

    def motion(self, from_ground: bool = False) -> Motion:
        """The rovers' flight in the time model; a flight that starts on the ground (a collection
        of landed rovers) first takes off: ``takeoff_time`` more."""
        return Motion(self.max_speed, self.accel, self.takeoff_time if from_ground else 0.0)


@dataclass(frozen=True)
class Fault:
    kind: str
    vehicle: str | None  # None = every vehicle
    at: float
    until: float | None  # None = never back
    rate: float | None = None  # packet_loss
    seconds: float | None = None  # latency
    factor: float | None = None  # battery_drain
    level: float | None = None  # low_battery: the battery reads at most this fraction
    distance: float | None = None  # land_drift: metres a rover's landing drifts east on its way down


@dataclass(frozen=True)
class SimConfig:
    speedup: float = 1.0
    faults: tuple[Fault, ...] = ()


@dataclass(frozen=True)
class SigningConfig:
    """MAVLink 2 signing: the 32-byte key is read from environment variable ``key_env`` (64 hex
    characters or base64), never from the mission file (docs/signing.md)."""

    key_env: str


@dataclass(frozen=True)
class LinksConfig:
    heartbeat_timeout: float = 3.0
    reassign_after: float = 10.0  # s a flying rover may stay lost before a spare takes its task
    signing: SigningConfig | None = None
    failsafe: str = "keep"  # link-loss action set on every vehicle before arming (FAILSAFE_ACTIONS)


@dataclass(frozen=True)
class GeofenceConfig:
    """``geofence:``: an inclusion polygon (ENU metres), the obstacles as exclusion zones, an
    optional height limit above home and what the autopilot does on a breach."""

    polygon: tuple[Vec2, ...]
    exclusions: tuple[tuple[Vec2, ...], ...] = ()
    alt_max: float | None = None
    action: str = "report"


@dataclass(frozen=True)
class RoadmapConfig:
    """Chapter 6 PRM parameters (eq. 6.5, 6.6); None = the roadmap planner's default."""

    xi1: float | None = None
    xi2: float | None = None
    xi3: float | None = None
    xi4: float | None = None
    phi: float | None = None


@dataclass(frozen=True)
class PlannerConfig:
    deploy: str = "lee"
    collect: str = "lee"
    seed: int = 0
    roadmap: RoadmapConfig | None = None
    budget_ms: float | None = None  # anytime improvement after the quick plan (None: quick plan only)


@dataclass(frozen=True)
class TlsConfig:
    ca: str | None = None
    cert: str | None = None
    key: str | None = None


@dataclass(frozen=True)
class MqttConfig:
    url: str
    topic_prefix: str
    client_id: str | None = None
    username: str | None = None
    password_env: str | None = None  # name of the environment variable holding the password
    tls: TlsConfig | None = None
    accept_task_changes: bool = False  # P/tasks/add|remove change the mission only when true


@dataclass(frozen=True)
class Mission:
    name: str
    origin: Origin | None
    carrier: CarrierConfig
    rovers: RoversConfig
    tasks: tuple[Task, ...]  # ENU metres, z = height above ground
    obstacles: tuple[tuple[Vec2, ...], ...]
    bounds: tuple[Vec2, Vec2] | None  # ((xmin, ymin), (xmax, ymax))
    collection: tuple[CollectRover, ...] | None
    sim: SimConfig
    links: LinksConfig
    planner: PlannerConfig
    dwell: float
    mqtt: MqttConfig | None
    raw: dict[str, Any]  # the parsed YAML as written (no defaults filled in)
    path: Path | None = None
    geofence: GeofenceConfig | None = None
    teams: tuple[TeamConfig, ...] = ()  # every carrier with its deck; () = one team (carrier, every rover)
    work: tuple[tuple[str, TaskWork], ...] = ()  # (task id, its duration and work mode) as the file gives
    operation: bool = False  # a long operation: rovers serve several tasks in sorties (docs/operations.md)

    def carrier_spec(self) -> CarrierSpec:
        """The carrier in the time model, with the rovers' take-off and touch-down times; it stops and
        turns at every vertex of a roadmap route, as it flies its mission of waypoints."""
        c, r = self.carrier, self.rovers
        return CarrierSpec(c.max_speed, c.accel, c.turn_rate, c.unload_time, c.load_time,
                           r.takeoff_time, r.land_time, vertex_stops=True)

    def _start(self) -> Vec3:
        return (self.carrier.position[0], self.carrier.position[1], 0.0)

    def deploy_problem(self) -> DeployProblem:
        if not self.tasks:
            raise MissionError(f"{self._where()}: tasks: the mission has no tasks to deploy rovers to")
        return DeployProblem(
            carrier=self.carrier_spec(),
            rover=self.rovers.motion(),
            deploy_range=self.rovers.deploy_range,
            start=self._start(),
            heading=compass_to_math(self.carrier.heading_deg),
            tasks=self.tasks,
            rovers=self.rovers.ids,
            takeoff_height=TAKEOFF_HEIGHT,
            **self.environment(),
        )

    def collect_problem(self) -> CollectProblem:
        if self.collection is None:
            raise MissionError(
                f"{self._where()}: collection: the mission has no 'collection' section; add "
                "collection: {rovers: [{id, position, range}, ...]} to plan a collection offline"
            )
        return CollectProblem(
            carrier=self.carrier_spec(),
            rover=self.rovers.motion(from_ground=any_on_ground(self.collection)),
            start=self._start(),
            heading=compass_to_math(self.carrier.heading_deg),
            rovers=self.collection,
            approach_height=MEET_HEIGHT,
            **self.environment(),
        )

    def operation_problem(self) -> OperationProblem:
        """The long operation (``operation: true``): every task with its work, the battery in
        seconds of flight, the battery swap on the deck (docs/operations.md)."""
        if not self.tasks:
            raise MissionError(f"{self._where()}: tasks: the mission has no tasks to work")
        r = self.rovers
        work = [self.task_work(t.id) for t in self.tasks]
        tasks = tuple(OpTask(t.id, t.position, w.duration, w.ground)
                      for t, w in zip(self.tasks, work, strict=True))
        return OperationProblem(
            carrier=self.carrier_spec(), rover=r.motion(), start=self._start(),
            heading=compass_to_math(self.carrier.heading_deg), tasks=tasks, rovers=r.ids,
            deploy_range=r.deploy_range, endurance=r.endurance_range / r.max_speed, reserve=r.reserve,
            swap_time=self.carrier.swap_time, takeoff_height=TAKEOFF_HEIGHT, approach_height=MEET_HEIGHT,
            seed=self.planner.seed)

    def task_work(self, task_id: str) -> TaskWork:
        """A task's work: as the file gives it, else (a task added later) ``dwell`` in ``rovers.work``."""
        return dict(self.work).get(task_id) or TaskWork(self.dwell, self.rovers.work == "ground")

    def planner_for(self, phase: str) -> str:
        """The planner a phase ("deploy" or "collect") uses when the command line names none: the
        mission's ``planner`` entry, or ``lee-graph`` for a mission with obstacles that names none
        (the open-space planners refuse obstacles)."""
        named = (self.raw.get("planner") or {}).get(phase)
        if named:
            return str(named)
        if self.obstacles:
            return "lee-graph"
        return self.planner.deploy if phase == "deploy" else self.planner.collect

    def environment(self) -> dict[str, Any]:
        """Chapter 6 fields of a planning problem: obstacles, bounds, roadmap parameters, seed, and
        the planning budget (``planner.budget_ms``).

        ``dataclasses.replace(problem, **mission.environment())`` gives any problem built from
        live state the mission's obstacles. Roadmap parameters left out of the file take the
        dissertation's values (planners.core.problem.RoadmapParams).
        """
        rc = self.planner.roadmap
        given = {} if rc is None else {k: v for k, v in vars(rc).items() if v is not None}
        return {"obstacles": self.obstacles, "bounds": self.bounds, "roadmap": RoadmapParams(**given),
                "seed": self.planner.seed, "budget_ms": self.planner.budget_ms}

    def _where(self) -> str:
        return str(self.path) if self.path is not None else self.name


def any_on_ground(rovers: Iterable[CollectRover]) -> bool:
    """A collection whose rovers (any of them) start on the ground: their flights take off first."""
    return any(r.position[2] <= GROUND_HEIGHT for r in rovers)
