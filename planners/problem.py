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
    """Straight-line motion capability: top speed (m/s) and acceleration (m/s², None = instant)."""

    max_speed: float
    accel: float | None = None


@dataclass(frozen=True)
class CarrierSpec:
    max_speed: float
    accel: float | None = None
    turn_rate: float | None = None  # rad/s, None = instantaneous turns
    unload_time: float = 0.0
    load_time: float = 0.0

    @cached_property
    def motion(self) -> Motion:
        return Motion(self.max_speed, self.accel)


@dataclass(frozen=True)
class Task:
    id: str
    position: Vec3


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
