"""The operation's times, composed from the time model of ``planners.core.timing`` (the one
source of truth for cost; docs/time-model.md, "Operations")."""

from __future__ import annotations

import dataclasses
from functools import lru_cache

from planners.core.problem import Motion, Vec3
from planners.core.timing import dist, leg_time
from planners.operations.problem import OperationProblem


@lru_cache(maxsize=64)
def _ground_motion(rover: Motion, takeoff: float) -> Motion:
    return dataclasses.replace(rover, fixed_time=takeoff)


def flight_time(p: Vec3, q: Vec3, problem: OperationProblem, from_ground: bool = False) -> float:
    """A rover's straight flight p → q (eq. 4.2); leaving a ground task it takes off first."""
    motion = _ground_motion(problem.rover, problem.carrier.takeoff_time) if from_ground else problem.rover
    return leg_time(dist(p, q), motion)


def launch_point(stop: Vec3, problem: OperationProblem) -> Vec3:
    """Where a launched rover's line starts: ``takeoff_height`` above the stop."""
    return (stop[0], stop[1], problem.takeoff_height)


def approach_point(stop: Vec3, problem: OperationProblem) -> Vec3:
    """Where a returning rover's line ends: ``approach_height`` above its pick-up stop."""
    return (stop[0], stop[1], problem.approach_height)


def land_start(arrive: float, meets: list[float]) -> float:
    """Rovers come down onto the deck once the carrier and the last of them are there (eq. 5.2)."""
    return max([arrive, *meets])


def stop_loaded(arrive: float, meets: list[float], problem: OperationProblem) -> float:
    """End of a stop's pick-ups: touch-down and loading after the last rover is there; ``arrive``
    when the stop picks up nobody."""
    if not meets:
        return arrive
    return land_start(arrive, meets) + problem.carrier.collect_stop_time


def stop_depart(loaded: float, launches: bool, problem: OperationProblem) -> float:
    """Departure: unloading and the launched rovers' take-off clearance after the pick-ups (eq. 4.3)."""
    return loaded + problem.carrier.deploy_stop_time if launches else loaded
