"""Time to go, for the views: per rover (to its task, or to touch-down on the carrier), for the
carrier (to the stop it drives to) and for the mission, from the plan being flown and the time
model (:mod:`planners.core.timing`).

A rover in the air has ``leg_time(rest of its path)`` to go (the rover motion of the mission); a
rover waiting on the deck, or a view without the mission's rover motion (``watch``), goes by the
plan: its leg's planned arrival minus the plan time now. A collected rover also waits for the
carrier at its meeting stop. The mission has the latest of these (and the plan's makespan) to go.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from planners.core.timing import leg_time

if TYPE_CHECKING:
    from fleetctl.run.state import FleetState, VehicleState

FLYING = frozenset({"climbing", "en_route", "returning"})
DONE = frozenset({"on_task", "loaded", "lost", "refused", "landed"})


@dataclass(frozen=True)
class PlannedLeg:
    """One rover's entry of the plan: the stop it belongs to and the planned times."""

    rover: str
    stop: int  # 0-based
    end: tuple[float, ...]  # where it flies to (task, or the meeting point)
    path: tuple[tuple[float, ...], ...]
    arrive: float  # planned arrival, plan seconds
    stop_arrive: float  # the carrier's planned arrival at the stop (collection: touch-down waits it)


def planned_legs(plan: dict[str, Any] | None) -> dict[str, PlannedLeg]:
    """rover id -> its leg in a plan JSON (``fleetctl.plan/1``)."""
    out: dict[str, PlannedLeg] = {}
    for k, stop in enumerate((plan or {}).get("stops") or []):
        for r in stop.get("rovers") or []:
            path = tuple(tuple(p) for p in (r.get("path") or []))
            end = tuple(r.get("target") or (path[-1] if path else stop.get("position") or (0, 0, 0)))
            rid = str(r.get("rover"))
            arrive, stop_arrive = float(r.get("arrive", 0.0)), float(stop.get("arrive", 0.0))
            out[rid] = PlannedLeg(rid, k, end, path, arrive, stop_arrive)
    return out


def path_left(path: Sequence[Sequence[float]], end: Sequence[float], at: Sequence[float]) -> float:
    """Metres still to fly from ``at`` along ``path`` (to ``end`` when there is no path): from the
    nearest segment's closest point on."""
    pts = [tuple(p) for p in path] or [tuple(end)]
    if len(pts) == 1:
        return math.dist(at[:3], pts[0][:3])
    best, rest_from, nearest = math.inf, 0, pts[-1]
    for i in range(len(pts) - 1):
        q = _closest(pts[i], pts[i + 1], at)
        d = math.dist(at[:3], q)
        if d < best:
            best, rest_from, nearest = d, i + 1, q
    rest = sum(math.dist(pts[i], pts[i + 1]) for i in range(rest_from, len(pts) - 1))
    return math.dist(nearest, pts[rest_from]) + rest


def _closest(a: Sequence[float], b: Sequence[float], p: Sequence[float]) -> tuple[float, ...]:
    ab = [b[i] - a[i] for i in range(3)]
    den = sum(x * x for x in ab)
    t = 0.0 if den == 0 else max(0.0, min(1.0, sum((p[i] - a[i]) * ab[i] for i in range(3)) / den))
    return tuple(a[i] + t * ab[i] for i in range(3))


def plan_now(state: FleetState) -> float:
    """Plan seconds now: since the plan's t = 0, else since the phase started."""
    if state.plan_started is not None:
        return max(0.0, state.mission_clock() - state.plan_started)
    return state.elapsed


def rover_time_to_go(state: FleetState, v: VehicleState,
                     legs: dict[str, PlannedLeg] | None = None) -> float | None:
    """Seconds until ``v`` reaches its task (deployment) or touches down (collection); None when it
    has nothing (more) to do in the plan."""
    legs = planned_legs(state.plan) if legs is None else legs
    leg = legs.get(v.id)
    if leg is None or v.lost or (v.state in DONE and not _waits_for_pickup(state, v)):
        return None
    by_plan = max(0.0, leg.arrive - plan_now(state))
    if v.state in FLYING and v.enu is not None and state.rover_motion is not None:
        togo = leg_time(path_left(leg.path, leg.end, v.enu), state.rover_motion)
    else:
        togo = by_plan
    if _is_collect(state):
        togo = max(togo, leg.stop_arrive - plan_now(state))
    return max(0.0, togo)


def carrier_time_to_go(state: FleetState) -> float | None:
    """Seconds until the carrier reaches the stop it drives to, by the plan; None when it holds."""
    stops = (state.plan or {}).get("stops") or []
    k = state.stop_index
    if state.vehicles.get(state.carrier_id) is None or state.vehicles[state.carrier_id].state != "driving":
        return None
    if not 1 <= k <= len(stops):
        return None
    return max(0.0, float(stops[k - 1].get("arrive") or 0.0) - plan_now(state))


def time_to_go(state: FleetState, v: VehicleState, legs: dict[str, PlannedLeg] | None = None) -> float | None:
    """A vehicle's time to go: a rover's (:func:`rover_time_to_go`), the carrier's to its next stop."""
    if v.role == "carrier":
        return carrier_time_to_go(state)
    return rover_time_to_go(state, v, legs)


def _is_collect(state: FleetState) -> bool:
    return (state.plan or {}).get("kind") == "collect"


def _waits_for_pickup(state: FleetState, v: VehicleState) -> bool:
    return _is_collect(state) and v.state in ("on_task", "landed")


def mission_time_to_go(state: FleetState) -> float | None:
    """Seconds until the phase's plan is done: the latest rover, at least the plan's makespan left
    (the dwell: its time left)."""
    if state.phase == "dwell":
        return None if state.planned is None else max(0.0, state.planned - state.elapsed)
    if state.plan is None or state.phase in ("done", "failed", "interrupted", "connect"):
        return None
    legs = planned_legs(state.plan)
    left = max(0.0, float(state.plan.get("makespan") or 0.0) - plan_now(state))
    rovers = (rover_time_to_go(state, v, legs) for v in state.vehicles.values() if v.id in legs)
    return max([left, *(t for t in rovers if t is not None)])


__all__ = ["PlannedLeg", "carrier_time_to_go", "mission_time_to_go", "path_left", "plan_now", "planned_legs",
           "rover_time_to_go", "time_to_go"]
