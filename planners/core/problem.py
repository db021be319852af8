"""Problem types shared by every planner: vehicles, tasks, rovers to collect.

All positions are local ENU metres (x east, y north, z up); headings are math radians
(0 = east, counter-clockwise). Conversion from mission files happens in ``fleetctl``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

Vec3 = tuple[float, float, float]


class PlanningError(ValueError):
    """A problem that no plan can satisfy (e.g. a task out of every rover's range)."""


@dataclass(frozen=True)
class Motion:
    """Straight-line motion capability: top speed (m/s), acceleration (m/s², None = instant) and
    the fixed time of every flight (s) on top of its travel.

    ``fixed_time`` is what a rover's flight costs whatever its length: in a deployment the take-off
    clearance (``rovers.takeoff_time``), in a collection the touch-down and disarm on the deck
    (``rovers.land_time``, plus ``takeoff_time`` when the rovers wait on the ground); 0 for the
    carrier and in the dissertation's model (docs/time-model.md).
    """

    max_speed: float
    accel: float | None = None
    fixed_time: float = 0.0


@dataclass(frozen=True)
class CarrierSpec:
    """The carrier's motion and its time at a stop (docs/time-model.md).

    At a deployment stop it unloads (``unload_time``), then waits while the rovers climb clear of
    the deck (``takeoff_time``, the rovers' take-off clearance) and leaves; the rovers' flights
    start when it leaves. At a collection stop every rover, once the carrier and the rover are
    both there, descends and touches down (``land_time``), then the carrier loads them
    (``load_time``). ``takeoff_time = land_time = 0`` is the dissertation's model.
    """

    max_speed: float
    accel: float | None = None
    turn_rate: float | None = None  # rad/s, None = instantaneous turns
    unload_time: float = 0.0
    load_time: float = 0.0
    takeoff_time: float = 0.0
    land_time: float = 0.0
    # a polyline leg (the roadmap) driven as rest-to-rest segments with a turn on the spot at each
    # inner vertex, as a ground carrier flying a mission of waypoints does; False = one leg over
    # the whole length with no inner turns (the dissertation's accounting)
    vertex_stops: bool = False

    @property
    def deploy_stop_time(self) -> float:
        """Arrival to departure at a deployment stop; the rovers' flights start at its end."""
        return self.unload_time + self.takeoff_time

    @property
    def collect_stop_time(self) -> float:
        """From the moment the carrier and the last of its rovers are there to departure."""
        return self.land_time + self.load_time

    @cached_property
    def motion(self) -> Motion:
        return Motion(self.max_speed, self.accel)


@dataclass(frozen=True)
class Task:
    id: str
    position: Vec3


Point2 = tuple[float, float]
Polygon2 = tuple[Point2, ...]


@dataclass(frozen=True)
class RoadmapParams:
    """Probabilistic roadmap parameters (dissertation ch. 6.3).

    ℵ₁ = √(w·h)·ξ₁ + ξ₂ nodes in the global PRM (eq. 6.5), ℵ_add = √(w_ROI·h_ROI)·ξ₃ + ξ₄ per
    local PRM (eq. 6.7), edges up to δ = max(d_deploy, (w+h)/2·φ) (eq. 6.6). ξ₁, ξ₂ and φ are the
    dissertation's values (Table 6.1, ch. 6.3.1); ξ₃, ξ₄ are not given in the text and are chosen
    so that Table 6.2's mission grows from 300 to about 390 nodes as in Table 6.3.
    """

    xi1: float = 1.5
    xi2: float = 150.0
    xi3: float = 1.0
    xi4: float = 10.0
    phi: float = 0.15


def refuse_obstacles(problem: DeployProblem | CollectProblem, planner: str) -> None:
    """Open-space planners (ch. 4–5) fly straight lines: refuse a problem with obstacles."""
    if problem.obstacles:
        raise PlanningError(
            f"the mission has {len(problem.obstacles)} obstacle(s) and the open-space planner {planner!r} "
            "would fly through them; use the roadmap planner: --planner lee-graph")


@dataclass(frozen=True)
class DeployProblem:
    """Chapter 4: drop rovers so that the last one reaches its task as early as possible."""

    carrier: CarrierSpec
    rover: Motion
    deploy_range: float  # d_deploy, metres of rover flight
    start: Vec3
    heading: float
    tasks: tuple[Task, ...]
    rovers: tuple[str, ...] = field(default=())  # rover ids in deck order; default r1..rN

    # Chapter 6: ground obstacles (polygons of unlimited height), the sampling workspace
    # ((xmin, ymin), (xmax, ymax)), roadmap parameters and the sampling seed.
    obstacles: tuple[Polygon2, ...] = ()
    bounds: tuple[Point2, Point2] | None = None
    roadmap: RoadmapParams = field(default_factory=RoadmapParams)
    seed: int = 0
    # height above the stop where a launched rover's line to its task starts (planners.core.approach);
    # 0 = from the deck, the dissertation's model
    takeoff_height: float = 0.0
    # Anytime planning (open-space ``lee``): None = the quick plan; a number = after it, improve
    # the plan (iterated local search, seeded by ``seed``) for about this many milliseconds of
    # wall time, counted from the planner's call, and return the best plan found.
    budget_ms: float | None = None
    # Rovers that cannot fly the whole ``deploy_range`` (a battery that is not full): (rover id,
    # metres of flight it may plan) pairs; a rover not listed has ``deploy_range``. Honoured by
    # every registered planner (planners.core.ranges.WithRoverRanges): such a rover flies only a
    # task it reaches.
    rover_ranges: tuple[tuple[str, float], ...] = ()

    def rover_range(self, rover: str) -> float:
        """Metres of flight ``rover`` may plan: its entry of ``rover_ranges``, at most ``deploy_range``."""
        return min(dict(self.rover_ranges).get(rover, self.deploy_range), self.deploy_range)

    def rover_ids(self) -> tuple[str, ...]:
        if self.rovers:
            return self.rovers
        return tuple(f"r{i + 1}" for i in range(len(self.tasks)))


@dataclass(frozen=True)
class CollectRover:
    id: str
    position: Vec3
    range: float  # metres of flight left for this rover (d_collect^i)


@dataclass(frozen=True)
class CollectProblem:
    """Chapter 5: pick every rover up so that the last one is loaded as early as possible."""

    carrier: CarrierSpec
    rover: Motion
    start: Vec3
    heading: float
    rovers: tuple[CollectRover, ...]

    # Chapter 6: ground obstacles (polygons of unlimited height), the sampling workspace
    # ((xmin, ymin), (xmax, ymax)), roadmap parameters and the sampling seed.
    obstacles: tuple[Polygon2, ...] = ()
    bounds: tuple[Point2, Point2] | None = None
    roadmap: RoadmapParams = field(default_factory=RoadmapParams)
    seed: int = 0
    # height above the stop where a rover's flight ends and its landing (land_time) begins
    # (planners.core.approach); 0 = on the deck, the dissertation's model
    approach_height: float = 0.0
    # Anytime planning (open-space ``lee``): None = the quick plan; a number = after it, improve
    # the plan (iterated local search, seeded by ``seed``) for about this many milliseconds of
    # wall time, counted from the planner's call, and return the best plan found.
    budget_ms: float | None = None
