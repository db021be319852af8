"""An independent check of plan JSON against the time model (docs/time-model.md), written from its text.

Written from the contract's text, not from planners/core/timing.py, so that a mistake in the time
model itself shows up as a disagreement. Used by the planner tests.
"""

from __future__ import annotations

import math
from typing import Any

TOL = 1e-4  # seconds / metres; plan JSON rounds times to 6 decimals, positions to 9


def _leg(s: float, v: float, a: float | None) -> float:
    if s <= 0:
        return 0.0
    if a is None:
        return s / v
    return s / v + v / a if s >= v * v / a else 2 * math.sqrt(s / a)


def _length(path: list[list[float]]) -> float:
    return sum(math.dist(p, q) for p, q in zip(path, path[1:], strict=False))


def check_plan(plan: dict[str, Any], carrier: dict[str, Any], rover: dict[str, Any],
               ranges: dict[str, float] | float, starts: dict[str, list[float]] | None = None) -> float:
    """Recompute every time of ``plan``; assert ranges; return the recomputed makespan.

    ``carrier``: max_speed, accel, turn_rate, unload_time, load_time (takeoff_time, land_time:
    default the plan's ``time_model``); ``rover``: max_speed, accel (fixed_time likewise);
    ``ranges``: one deploy range, or each rover's range (collection); ``starts``: collection
    rovers' positions.
    """
    assert plan["schema"] == "fleetctl.plan/1"
    # the time model's terms beyond the dissertation (docs/time-model.md): the caller's, or the
    # plan's own report of them; both must agree when both are there
    reported = plan.get("time_model", {})
    takeoff = carrier.get("takeoff_time", reported.get("takeoff_time", 0.0))
    land = carrier.get("land_time", reported.get("land_time", 0.0))
    fixed = rover.get("fixed_time", reported.get("rover_fixed_time", 0.0))
    for k, v in (("takeoff_time", takeoff), ("land_time", land), ("rover_fixed_time", fixed)):
        assert abs(reported.get(k, v) - v) < TOL, (k, reported.get(k), v)
    vertex_stops = carrier.get("vertex_stops", reported.get("vertex_stops", False))
    assert reported.get("vertex_stops", vertex_stops) == vertex_stops
    heading = plan["carrier"]["heading"]
    prev = plan["carrier"]["start"]
    t = 0.0
    eta = 0.0
    makespan = 0.0
    for stop in plan["stops"]:
        path = stop.get("carrier_path") or [prev, stop["position"]]
        assert math.dist(path[0], prev) < TOL and math.dist(path[-1], stop["position"]) < TOL
        segs = [(q[0] - p[0], q[1] - p[1]) for p, q in zip(path, path[1:], strict=False)]
        segs = [s for s in segs if math.hypot(*s) > 1e-9]
        dt = 0.0
        # a roadmap route with vertex stops: rest-to-rest segments, a turn on the spot at each
        pieces = [(s, math.hypot(*s)) for s in segs] if vertex_stops else (
            [(segs[0], _length(path))] if segs else [])
        for seg, length in pieces:
            h = math.atan2(seg[1], seg[0])
            turn = abs((h - heading + math.pi) % (2 * math.pi) - math.pi)
            if carrier["turn_rate"] is not None:
                dt += turn / carrier["turn_rate"]
            dt += _leg(length, carrier["max_speed"], carrier["accel"])
            heading = h
        if segs:
            heading = math.atan2(segs[-1][1], segs[-1][0])
        if plan["kind"] == "deploy":
            t += dt
            assert abs(stop["arrive"] - t) < TOL, (stop["arrive"], t)
            t += carrier["unload_time"] + takeoff  # unloaded, then the rovers climb clear of the deck
            assert abs(stop["depart"] - t) < TOL
            for r in stop["rovers"]:
                rpath = r.get("path") or [stop["position"], r["target"]]
                lift = reported.get("takeoff_height", 0.0)  # the line starts this high above the stop
                assert math.dist(rpath[0], [*stop["position"][:2], lift]) < TOL
                assert math.dist(rpath[-1], r["target"]) < TOL
                length = _length(rpath)
                limit = ranges if isinstance(ranges, float | int) else ranges[r["rover"]]
                assert length <= limit + 1e-6, (r, length, limit)
                arr = t + fixed + _leg(length, rover["max_speed"], rover["accel"])
                assert abs(r["arrive"] - arr) < TOL, (r["arrive"], arr)
                makespan = max(makespan, arr)
        else:
            here = eta + dt
            assert abs(stop["arrive"] - here) < TOL, (stop["arrive"], here)
            latest = here
            for r in stop["rovers"]:
                rpath = r["path"]
                if starts is not None:
                    assert math.dist(rpath[0], starts[r["rover"]]) < TOL
                approach = reported.get("approach_height", 0.0)  # flights end this high above the stop
                assert math.dist(rpath[-1], [*stop["position"][:2], approach]) < TOL
                length = _length(rpath)
                assert isinstance(ranges, dict)
                assert length <= ranges[r["rover"]] + 1e-6, (r, length)
                arr = fixed + _leg(length, rover["max_speed"], rover["accel"])
                assert abs(r["arrive"] - arr) < TOL
                latest = max(latest, arr)
            eta = latest + land + carrier["load_time"]  # down onto the deck, then loaded
            assert abs(stop["depart"] - eta) < TOL, (stop["depart"], eta)
            assert stop["depart"] >= max([r["arrive"] for r in stop["rovers"]] + [stop["arrive"]]) \
                + land + carrier["load_time"] - TOL
            makespan = eta
        prev = stop["position"]
    assert abs(plan["makespan"] - makespan) < TOL, (plan["makespan"], makespan)
    return makespan
