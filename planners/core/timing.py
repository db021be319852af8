"""The time model (docs/time-model.md; dissertation eq. 4.2, 4.3, 5.2, 6.2).

This module is the one source of truth for mission times: planners, baselines, lower bounds,
benchmarks and the controller's ETA all call it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import TypeVar

import numpy as np

from planners.core.native import kernels
from planners.core.plan import Plan
from planners.core.problem import CarrierSpec, CollectProblem, DeployProblem, Motion, Vec3

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


def remaining_leg_time(length: float, speed: float, motion: Motion) -> float:
    """Time to cover the last ``length`` metres of a leg, moving at ``speed`` now and at rest at
    its end (eq. 4.2's profile entered part-way: accelerate to the top speed, cruise, brake).

    ``speed = 0`` gives :func:`travel_time`. For live estimates (the carrier's ETA at its stop).
    """
    if length <= 0.0:
        return 0.0
    v, a = motion.max_speed, motion.accel
    v0 = min(max(speed, 0.0), v)
    if a is None:
        return length / v
    if length <= v0 * v0 / (2.0 * a):  # inside its braking distance: brakes at ``a`` from sqrt(2·a·length)
        return math.sqrt(2.0 * length / a)
    ramp = (v * v - v0 * v0) / (2.0 * a) + v * v / (2.0 * a)
    if length >= ramp:
        return (v - v0) / a + v / a + (length - ramp) / v
    peak = math.sqrt((2.0 * a * length + v0 * v0) / 2.0)
    return (peak - v0) / a + peak / a


def dissertation_model(problem: P) -> P:
    """The same problem under the dissertation's time model: no take-off clearance, no
    touch-down time, no fixed per-flight time (the paper tables in bench/ are computed this way so
    that they stay comparable with the text)."""
    c, r = problem.carrier, problem.rover
    flat = (problem.approach_height == 0.0 if isinstance(problem, CollectProblem)
            else problem.takeoff_height == 0.0)
    if c.takeoff_time == 0.0 and c.land_time == 0.0 and r.fixed_time == 0.0 and not c.vertex_stops and flat:
        return problem
    paper = dataclasses.replace(c, takeoff_time=0.0, land_time=0.0, vertex_stops=False)
    out = dataclasses.replace(problem, carrier=paper, rover=dataclasses.replace(r, fixed_time=0.0))
    if isinstance(out, CollectProblem):
        return dataclasses.replace(out, approach_height=0.0)
    return dataclasses.replace(out, takeoff_height=0.0)


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

    The carrier turns at the stop from ``heading`` to the direction of the leg's first segment.
    A polyline leg (the roadmap) is one leg over its whole length with no inner turns, or, with
    ``carrier.vertex_stops``, rest-to-rest segments with a turn at each inner vertex
    (docs/time-model.md).
    """
    headings = _segment_headings(path)
    if not headings:
        return 0.0, heading
    if not carrier.vertex_stops or len(headings) == 1:
        t = turn_time(heading, headings[0], carrier.turn_rate) + leg_time(path_length(path), carrier.motion)
        return t, headings[-1]
    t, h = 0.0, heading
    for p, q in zip(path, path[1:], strict=False):
        dt, h = carrier_hop(p, q, h, carrier)
        t += dt
    return t, h


def carrier_hop(p: Sequence[float], q: Sequence[float], heading: float,
                carrier: CarrierSpec) -> tuple[float, float]:
    """``carrier_leg`` for a straight ground leg p → q, for planners' inner loops.

    The same numbers as ``carrier_leg`` (turn at the start + eq. 4.2), written out inline because
    planners call it hundreds of thousands of times; tests check that the two agree.
    """
    return carrier_step(q[0] - p[0], q[1] - p[1], heading, carrier)


def carrier_step(dx: float, dy: float, heading: float, carrier: CarrierSpec) -> tuple[float, float]:
    """:func:`carrier_hop` for the ground displacement (dx, dy): time and the heading after it."""
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


Step = Callable[[float, float, float], tuple[float, float]]
Hop = Callable[[Sequence[float], Sequence[float], float], tuple[float, float]]


def carrier_stepper(carrier: CarrierSpec) -> Step:
    """:func:`carrier_step` with ``carrier``'s numbers bound once: ``step(dx, dy, heading)``, the same
    arithmetic in the same order (the same floats, bit for bit; a test checks), for the planners'
    innermost loops, which call it millions of times."""
    v, a, w = carrier.max_speed, carrier.accel, carrier.turn_rate
    if kernels is not None:  # the compiled twin (planners.core.native): the same floats
        return kernels.Stepper(v, a, w)
    return _python_stepper(v, a, w)


def _python_stepper(v: float, a: float | None, w: float | None) -> Step:
    """``carrier_stepper`` in Python (the compiled ``Stepper``'s twin)."""
    atan2, sqrt, tau = math.atan2, math.sqrt, _TAU
    ramp = None if a is None else v * v / a
    brake = None if a is None else v / a

    def step(dx: float, dy: float, heading: float) -> tuple[float, float]:
        d2 = dx * dx + dy * dy
        if d2 <= 1e-18:
            return 0.0, heading
        h = atan2(dy, dx)
        length = sqrt(d2)
        if a is None:
            t = length / v
        elif length >= ramp:  # type: ignore[operator]
            t = length / v + brake  # type: ignore[operator]
        else:
            t = 2.0 * sqrt(length / a)
        if w is not None:
            turn = (h - heading) % tau
            t += (turn if turn <= tau - turn else tau - turn) / w
        return t, h
    return step


def carrier_hopper(carrier: CarrierSpec) -> Hop:
    """:func:`carrier_hop` with ``carrier``'s numbers bound once (``carrier_stepper``):
    ``hop(p, q, heading)``."""
    if kernels is not None:
        return kernels.Hopper(carrier.max_speed, carrier.accel, carrier.turn_rate)
    step = carrier_stepper(carrier)
    return lambda p, q, heading: step(q[0] - p[0], q[1] - p[1], heading)


def leg_timer(motion: Motion) -> Callable[[float], float]:
    """:func:`leg_time` with ``motion``'s numbers bound once: ``leg(length)``, the same floats."""
    v, a, fixed = motion.max_speed, motion.accel, motion.fixed_time
    if kernels is not None:
        return kernels.Leg(v, a, fixed)
    return _python_leg(v, a, fixed)


def _python_leg(v: float, a: float | None, fixed: float) -> Callable[[float], float]:
    """``leg_timer`` in Python (the compiled ``Leg``'s twin)."""
    ramp = None if a is None else v * v / a
    brake = None if a is None else v / a
    sqrt = math.sqrt

    def leg(length: float) -> float:
        if length <= 0.0:
            return fixed + 0.0
        if a is None:
            return fixed + length / v
        if length >= ramp:  # type: ignore[operator]
            return fixed + (length / v + brake)  # type: ignore[operator]
        return fixed + 2.0 * sqrt(length / a)
    return leg


def travel_times(length: np.ndarray, motion: Motion) -> np.ndarray:
    """:func:`travel_time` of every element of ``length`` (numpy, lengths >= 0): the same profile,
    written without branches as 2·sqrt(min(L, v²/a)/a) + max(L − v²/a, 0)/v (equal to eq. 4.2's
    two branches up to rounding)."""
    v, a = motion.max_speed, motion.accel
    if a is None:
        return length / v
    ramp = v * v / a
    return 2.0 * np.sqrt(np.minimum(length, ramp) / a) + np.maximum(length - ramp, 0.0) / v


def leg_times(length: np.ndarray, motion: Motion) -> np.ndarray:
    """:func:`leg_time` of every element of ``length`` (numpy)."""
    return motion.fixed_time + travel_times(length, motion)


def carrier_steps(dx: np.ndarray, dy: np.ndarray, heading: np.ndarray | float,
                  carrier: CarrierSpec) -> tuple[np.ndarray, np.ndarray]:
    """:func:`carrier_step` of every element (numpy, broadcast): times and headings after them,
    for planners that score many candidate stops at once."""
    d2 = dx * dx + dy * dy
    h = np.arctan2(dy, dx)
    t = travel_times(np.sqrt(d2), carrier.motion)
    still = d2 <= 1e-18
    if still.any():  # no drive: no turn, the heading is kept
        h = np.where(still, heading, h)
        t = np.where(still, 0.0, t)
    if carrier.turn_rate is not None:
        turn = (h - heading) % _TAU
        t = t + np.minimum(turn, _TAU - turn) / carrier.turn_rate
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

    At stop k the carrier arrives, unloads once for ``unload_time``, waits ``takeoff_time`` while
    its rovers climb clear of the deck and leaves; the rovers' flights start then (eq. 4.3 with
    the clearance). Makespan = the last rover's arrival.
    """
    t = 0.0
    arrive, depart, rover_arrive = [], [], []
    makespan = 0.0
    for path, lengths in zip(carrier_paths, rover_lengths, strict=True):
        dt, heading = carrier_leg(path, heading, carrier)
        t += dt
        arrive.append(t)
        t += carrier.deploy_stop_time
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

    eta_k = max(eta_{k-1} + rotation + leg_k, latest rover arrival at k) + land_time + load_time:
    a rover comes down onto the deck once both are there (``land_time``), then it is loaded.
    Returns each stop's carrier arrival, departure (= eta_k), rover arrivals, and the makespan.
    """
    eta = 0.0
    arrive, depart, rover_arrive = [], [], []
    for path, lengths in zip(carrier_paths, rover_lengths, strict=True):
        dt, heading = carrier_leg(path, heading, carrier)
        here = eta + dt
        arr = [leg_time(length, rover) for length in lengths]
        eta = max([here, *arr]) + carrier.collect_stop_time
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
    plan.time_model = time_model_terms(carrier, rover)
    return plan


def time_model_terms(carrier: CarrierSpec, rover: Motion) -> dict[str, float | bool]:
    """The terms beyond the dissertation's model, as the plan JSON reports them."""
    return {"takeoff_time": carrier.takeoff_time, "land_time": carrier.land_time,
            "rover_fixed_time": rover.fixed_time, "vertex_stops": carrier.vertex_stops}
