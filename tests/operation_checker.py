"""An independent check of an operation plan's JSON (docs/plan-json.md "An operation plan",
docs/time-model.md "Operations").

Written from the documents' formulas, not from planners/ (no import of it), so that a mistake in
the planner's own time keeping shows up as a disagreement. It recomputes every time of the
schedule and asserts: every task worked once for its duration, no rover below its reserve, no
rover in two places (its sorties in order, launched only from the deck, swaps only on the deck), a
battery carried from one sortie to the next unless swapped, the carrier's stops consistent with their
launches and pick-ups, one swap at a time, every rover back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

TOL = 1e-4  # s / m: the plan JSON rounds times to 6 decimals, positions to 9


@dataclass(frozen=True)
class OpSpec:
    """What the checker needs of the mission, in its own words (docs/time-model.md symbols)."""

    v_c: float
    a_c: float | None
    omega: float | None
    u: float  # unload_time
    l: float  # load_time  # noqa: E741
    tau: float  # rovers.takeoff_time
    lam: float  # rovers.land_time
    v_r: float
    a_r: float | None
    deploy_range: float
    endurance: float  # s in the air on a full battery (endurance_range / max_speed)
    reserve: float
    swap: float
    h_t: float  # takeoff height
    h_a: float  # approach height
    tasks: dict[str, tuple[tuple[float, float, float], float, bool]]  # id -> position, duration, ground
    rovers: tuple[str, ...]


def T(s: float, v: float, a: float | None) -> float:
    """Eq. 4.2: rest-to-rest leg of length s."""
    if s <= 0:
        return 0.0
    if a is None:
        return s / v
    return s / v + v / a if s >= v * v / a else 2.0 * math.sqrt(s / a)


def _fly(spec: OpSpec, p: list[float], q: list[float], from_ground: bool) -> float:
    return (spec.tau if from_ground else 0.0) + T(math.dist(p, q), spec.v_r, spec.a_r)


def _carrier(spec: OpSpec, prev: list[float], path: list[list[float]], heading: float) -> tuple[float, float]:
    """Turn at the stop left + the leg over the path's whole length (a straight leg here)."""
    assert math.dist(path[0], prev) < TOL
    segs = [(q[0] - p[0], q[1] - p[1]) for p, q in zip(path, path[1:], strict=False)]
    segs = [s for s in segs if math.hypot(*s) > 1e-9]
    if not segs:
        return 0.0, heading
    h = math.atan2(segs[0][1], segs[0][0])
    turn = abs((h - heading + math.pi) % (2 * math.pi) - math.pi)
    t = (turn / spec.omega if spec.omega is not None else 0.0)
    t += T(sum(math.hypot(*s) for s in segs), spec.v_c, spec.a_c)
    return t, math.atan2(segs[-1][1], segs[-1][0])


def check_operation(plan: dict[str, Any], spec: OpSpec) -> float:
    """Recompute and assert the whole schedule; return the recomputed makespan."""
    assert plan["schema"] == "fleetctl.plan/1" and plan["kind"] == "operation"
    stops, sorties = plan["stops"], plan["sorties"]
    lands = _check_stops(plan, spec)
    for s in sorties:
        _check_sortie(s, stops, lands, spec)
    _check_tasks(sorties, spec)
    _check_rovers(plan, spec)
    end = stops[-1]["depart"] if stops else 0.0
    assert all(s["pickup_stop"] >= 0 for s in sorties), "a rover is never picked up"
    assert all(s["aboard"] <= end + TOL for s in sorties)
    assert abs(plan["makespan"] - end) < TOL, (plan["makespan"], end)
    return end


def _check_stops(plan: dict[str, Any], spec: OpSpec) -> list[float]:
    """Carrier legs and each stop's pick-up and launch times; returns each stop's landing start."""
    sorties = plan["sorties"]
    prev, heading, depart = plan["carrier"]["start"], plan["carrier"]["heading"], 0.0
    lands = []
    for k, stop in enumerate(plan["stops"]):
        path = stop.get("carrier_path") or [prev, stop["position"]]
        assert math.dist(path[-1], stop["position"]) < TOL
        dt, heading = _carrier(spec, prev, path, heading)
        assert stop["arrive"] >= depart + dt - TOL, ("carrier there too early", k, stop["arrive"],
                                                     depart + dt)
        picked = sorted(s["rover"] for s in sorties if s["pickup_stop"] == k)
        launched = sorted(s["rover"] for s in sorties if s["launch_stop"] == k)
        assert picked == sorted(stop["pickups"]) and launched == sorted(stop["launches"]), k
        assert picked or launched, f"stop {k} neither picks up nor launches"
        meets = [s["meet"] for s in sorties if s["pickup_stop"] == k]
        land = max([stop["arrive"], *meets])
        loaded = land + spec.lam + spec.l if picked else stop["arrive"]
        assert abs(stop["loaded"] - loaded) < TOL, (k, stop["loaded"], loaded)
        out = loaded + spec.u + spec.tau if launched else loaded
        assert abs(stop["depart"] - out) < TOL, (k, stop["depart"], out)
        lands.append(land)
        prev, depart = stop["position"], stop["depart"]
    return lands


def _check_sortie(s: dict[str, Any], stops: list[dict[str, Any]], lands: list[float], spec: OpSpec) -> None:
    """A sortie's flights, work and battery."""
    a, b = stops[s["launch_stop"]], stops[s["pickup_stop"]]
    assert s["pickup_stop"] > s["launch_stop"], "picked up before it was launched"
    assert abs(s["depart"] - a["depart"]) < TOL and abs(s["takeoff"] - (a["depart"] - spec.tau)) < TOL
    here, t, ground, on_ground = [a["position"][0], a["position"][1], spec.h_t], s["depart"], False, 0.0
    assert s["visits"], "a sortie without a task"
    assert math.dist(here, s["visits"][0]["position"]) <= spec.deploy_range + 1e-6, "launch flight too long"
    for v in s["visits"]:
        pos, duration, task_ground = spec.tasks[v["task"]]
        assert math.dist(v["position"], pos) < TOL and (v["work"] == "ground") == task_ground
        arrive = t + _fly(spec, here, pos, ground)
        assert abs(v["arrive"] - arrive) < TOL, (v, arrive)
        assert abs(v["end"] - (arrive + duration)) < TOL and v["leave"] >= v["end"] - TOL
        if task_ground:
            on_ground += v["leave"] - v["arrive"]
        here, t, ground = pos, v["leave"], task_ground
    meet = t + _fly(spec, here, [b["position"][0], b["position"][1], spec.h_a], ground)
    assert abs(s["meet"] - meet) < TOL, (s["meet"], meet)
    land = lands[s["pickup_stop"]]
    assert meet <= land + TOL
    assert abs(s["landed"] - (land + spec.lam)) < TOL and abs(s["aboard"] - b["loaded"]) < TOL
    air = s["landed"] - s["takeoff"] - on_ground
    assert abs(s["air_time"] - air) < TOL, (s["air_time"], air)
    assert abs(s["battery_left"] - (s["battery_start"] - air / spec.endurance)) < TOL
    assert s["battery_left"] >= spec.reserve - TOL, \
        f"{s['rover']} below its reserve ({s['battery_left']:.4f})"


def _check_tasks(sorties: list[dict[str, Any]], spec: OpSpec) -> None:
    worked = [v["task"] for s in sorties for v in s["visits"]]
    assert sorted(worked) == sorted(spec.tasks), "every task exactly once"


def _check_rovers(plan: dict[str, Any], spec: OpSpec) -> None:
    """Each rover: sorties one after another, a swap on the deck between two; one swap at a time."""
    sorties, stops = plan["sorties"], plan["stops"]
    swaps = [(r, e) for r, rows in plan["rovers"].items() for e in rows if e["kind"] == "swap"]
    for _, e in swaps:
        assert abs(e["to"] - e["from"] - spec.swap) < TOL
    ordered = sorted((e["from"], e["to"]) for _, e in swaps)
    for (_, end), (start, _) in zip(ordered, ordered[1:], strict=False):
        assert start >= end - TOL, "two swaps at once"
    for rover in {s["rover"] for s in sorties} | {r for r, _ in swaps}:
        assert rover in spec.rovers
        own = sorted((s for s in sorties if s["rover"] == rover), key=lambda s: s["takeoff"])
        mine = [e for r, e in swaps if r == rover]
        # on the deck: before the first sortie, between two, after the last (swaps happen only there)
        deck = [(-math.inf, stops[o["launch_stop"]]["loaded"] if (o := (own or [None])[0]) else math.inf)]
        deck += [(s["aboard"], stops[n["launch_stop"]]["loaded"]) for s, n in zip(own, own[1:], strict=False)]
        deck += [(own[-1]["aboard"], math.inf)] if own else []
        for e in mine:
            assert any(e["from"] >= a - TOL and e["to"] <= b + TOL for a, b in deck), \
                f"{rover} swapped in the air"
        battery = 1.0  # every rover starts on a full battery; a swap fills it again
        for k, s in enumerate(own):
            if k and any(e["from"] >= deck[k][0] - TOL and e["to"] <= deck[k][1] + TOL for e in mine):
                battery = 1.0
            assert abs(s["battery_start"] - battery) < TOL, (f"{rover} launched without its battery swap", s)
            battery = s["battery_left"]
        for s, nxt in zip(own, own[1:], strict=False):
            assert nxt["launch_stop"] >= s["pickup_stop"], "in two places"
            assert nxt["takeoff"] >= s["aboard"] - TOL, "in two places"
