"""The time model (DESIGN.md "Time model"; dissertation eq. 4.2, 4.3, 5.2, 6.2).

This module is the one source of truth for mission times: planners, baselines, lower bounds,
benchmarks and the controller's ETA all call it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import TypeVar

from planners.plan import Plan
from planners.problem import CarrierSpec, CollectProblem, DeployProblem, Motion, Vec3

P = TypeVar("P", DeployProblem, CollectProblem)

# Planners keep rover flights this far inside their range so that a plan whose coordinates are
# rounded for JSON still satisfies the range when recomputed.
RANGE_MARGIN = 1e-5
_TAU = 2.0 * math.pi


def leg_time(length: float, motion: Motion) -> float:
    """Eq. 4.2 without rotation: rest-to-rest travel of ``length`` metres, plus the motion's
    fixed per-flight time (take-off clearance or touch-down; 0 for the carrier)."""
    return motion.fixed_time + travel_time(length, motion)


def travel_time(length: float, motion: Motion) -> float:
    """Eq. 4.2 without rotation and without the fixed time: rest-to-rest travel of ``length`` m."""
    if length <= 0.0:
        return 0.0
    v, a = motion.max_speed, motion.accel
    if a is None:
        return length / v
    if length >= v * v / a:
        return length / v + v / a
    return 2.0 * math.sqrt(length / a)


def dissertation_model(problem: P) -> P:
    """The same problem under the dissertation's time model: no fixed per-flight time (the paper
    tables in bench/ are computed this way so that they stay comparable with the text)."""
    if problem.rover.fixed_time == 0.0:
        return problem
    return dataclasses.replace(problem, rover=dataclasses.replace(problem.rover, fixed_time=0.0))


def dist(p: Sequence[float], q: Sequence[float]) -> float:
    return math.dist(p, q)


def path_length(path: Sequence[Vec3]) -> float:
    return sum(dist(path[i], path[i + 1]) for i in range(len(path) - 1))


def heading_change(h_from: float, h_to: float) -> float:
    """Smallest absolute angle between two headings, in [0, π]."""
    d = (h_to - h_from) % (2.0 * math.pi)
    return min(d, 2.0 * math.pi - d)


def turn_time(h_from: float, h_to: float, turn_rate: float | None) -> float:
    if turn_rate is None:
        return 0.0
    return heading_change(h_from, h_to) / turn_rate


def _segment_headings(path: Sequence[Vec3]) -> list[float]:
    """Headings of the path's ground segments of non-zero length."""
    out = []
    for p, q in zip(path, path[1:], strict=False):
        dx, dy = q[0] - p[0], q[1] - p[1]
        if dx * dx + dy * dy > 1e-18:
            out.append(math.atan2(dy, dx))
    return out


def carrier_leg(path: Sequence[Vec3], heading: float, carrier: CarrierSpec) -> tuple[float, float]:
    """Time to drive a carrier leg (rotation at its start + travel) and the heading afterwards.

    The carrier turns at the stop from ``heading`` to the direction of the leg's first segment;
    turns at intermediate vertices of a polyline leg are not charged (DESIGN.md).
    """
    headings = _segment_headings(path)
    if not headings:
        return 0.0, heading
    t = turn_time(heading, headings[0], carrier.turn_rate) + leg_time(path_length(path), carrier.motion)
    return t, headings[-1]


def carrier_hop(p: Sequence[float], q: Sequence[float], heading: float,
                carrier: CarrierSpec) -> tuple[float, float]:
    """``carrier_leg`` for a straight ground leg p → q, for planners' inner loops.

    The same numbers as ``carrier_leg`` (turn at the start + eq. 4.2), written out inline because
    planners call it hundreds of thousands of times; tests check that the two agree.
    """
    dx, dy = q[0] - p[0], q[1] - p[1]
    d2 = dx * dx + dy * dy
    if d2 <= 1e-18:
        return 0.0, heading
    h = math.atan2(dy, dx)
    length = math.sqrt(d2)
    v, a = carrier.max_speed, carrier.accel
    if a is None:
        t = length / v
    elif length >= v * v / a:
        t = length / v + v / a
    else:
        t = 2.0 * math.sqrt(length / a)
    if carrier.turn_rate is not None:
        turn = (h - heading) % _TAU
        t += min(turn, _TAU - turn) / carrier.turn_rate
    return t, h


def deploy_schedule(
    start: Vec3,
    heading: float,
    carrier_paths: Sequence[Sequence[Vec3]],
    rover_lengths: Sequence[Sequence[float]],
    carrier: CarrierSpec,
    rover: Motion,
) -> tuple[list[float], list[float], list[list[float]], float]:
    """Deployment times: each stop's arrival and departure, each rover's arrival, the makespan.

    At stop k the carrier arrives, unloads once for ``unload_time`` and leaves; its rovers
    depart when unloading ends (eq. 4.3). Makespan = the last rover's arrival.
    """
    t = 0.0
    arrive, depart, rover_arrive = [], [], []
    makespan = 0.0
    for path, lengths in zip(carrier_paths, rover_lengths, strict=True):
        dt, heading = carrier_leg(path, heading, carrier)
        t += dt
        arrive.append(t)
        t += carrier.unload_time
        depart.append(t)
        arr = [t + leg_time(length, rover) for length in lengths]
        rover_arrive.append(arr)
        if arr:
            makespan = max(makespan, max(arr))
    return arrive, depart, rover_arrive, makespan


def collect_schedule(
    start: Vec3,
    heading: float,
    carrier_paths: Sequence[Sequence[Vec3]],
    rover_lengths: Sequence[Sequence[float]],
    carrier: CarrierSpec,
    rover: Motion,
) -> tuple[list[float], list[float], list[list[float]], float]:
    """Collection times (eq. 5.2): rovers all start at t = 0; the carrier waits for late rovers.

    eta_k = max(eta_{k-1} + rotation + leg_k, latest rover arrival at k) + load_time.
    Returns each stop's carrier arrival, departure (= eta_k), rover arrivals, and the makespan.
    """
    eta = 0.0
    arrive, depart, rover_arrive = [], [], []
    for path, lengths in zip(carrier_paths, rover_lengths, strict=True):
        dt, heading = carrier_leg(path, heading, carrier)
        here = eta + dt
        arr = [leg_time(length, rover) for length in lengths]
        eta = max([here, *arr]) + carrier.load_time
        arrive.append(here)
        depart.append(eta)
        rover_arrive.append(arr)
    return arrive, depart, rover_arrive, (eta if carrier_paths else 0.0)


def retime(plan: Plan, carrier: CarrierSpec, rover: Motion) -> Plan:
    """Fill in every time of ``plan`` (stops, rovers, makespan, carrier distance) from its paths."""
    schedule = deploy_schedule if plan.kind == "deploy" else collect_schedule
    paths = [s.carrier_path for s in plan.stops]
    lengths = [[path_length(leg.path) for leg in s.rovers] for s in plan.stops]
    arrive, depart, rover_arrive, makespan = schedule(plan.start, plan.heading, paths, lengths,
                                                      carrier, rover)
    for stop, a, d, ra in zip(plan.stops, arrive, depart, rover_arrive, strict=True):
        stop.arrive, stop.depart = a, d
        for leg, t in zip(stop.rovers, ra, strict=True):
            leg.arrive = t
    plan.makespan = makespan
    plan.carrier_distance = sum(path_length(p) for p in paths)
    return plan
