"""What the web map shows, as JSON (the page draws it; :mod:`fleetctl.views.web` serves it).

* :func:`plan_layer` - tasks, carrier stops, the planned carrier route and the rovers' planned
  paths, in ENU metres, from the plan being flown (and the mission's tasks);
* :func:`frame` - one moment: ``T`` (mission seconds since the run started), phase, stop k of N,
  time to go, and per vehicle its state, task, ENU position, battery and link level, time to go;
* :class:`Trails` - the last positions of every vehicle (a bounded history a new page starts with);
* :func:`teams_plan` and :func:`teams_frame` - the same for every team a view shows
  (:class:`~fleetctl.views.teams.ShownTeams`): the documents the page gets.

The page's documents: ``plan`` = ``{"kind", "makespan", "tasks": [{id, e, n, u, team}],
"teams": [{"team", "colour", "kind", "makespan", "route", "stops", "paths"}]}`` and ``frame`` =
``{"mission", "T", "phase", "stop", "stops", "elapsed", "planned", "ttg", "replans", "operation" (a long
operation: :func:`_operation`, else null; one team), "teams":
[{"team", "colour", "phase", "stop", "stops", "elapsed", "planned", "ttg", "eta", "replans"}],
"vehicles": [{..., "team"}], "events": [{"T", "kind", "text", "team"}]}``. One state (a one-team
run, replay, a one-team watch) is one entry of ``teams`` whose ``team`` and ``colour`` are null,
and the frame's top-level fields are its own; with several teams they are the run's: ``T`` and
``ttg`` the latest of the teams', ``phase`` the teams' phases, ``stop``/``stops`` 0.
"""

from __future__ import annotations

import math
from collections import deque
from typing import TYPE_CHECKING, Any

from fleetctl.views.eta import mission_time_to_go, planned_legs, time_to_go
from fleetctl.views.levels import battery_level, link_level

if TYPE_CHECKING:
    from fleetctl.run.state import FleetState, VehicleState
    from fleetctl.views.teams import ShownTeams

TRAIL_POINTS = 400  # positions kept per vehicle
TRAIL_STEP = 0.5  # m: a new trail point once a vehicle moved this far
EVENTS_SHOWN = 8
ON_DECK = frozenset({"on_deck", "loaded", "unknown"})


def _r(x: float | None, nd: int = 2) -> float | None:
    return None if x is None or not math.isfinite(x) else round(float(x), nd)


def plan_layer(state: FleetState) -> dict[str, Any]:
    """Tasks, stops, route and rover paths (ENU metres) of the current plan."""
    plan = state.plan or {}
    tasks = {tid: list(p) for tid, p in state.tasks.items()}
    route: list[list[float]] = []
    start = (plan.get("carrier") or {}).get("start")
    if start:
        route.append([start[0], start[1]])
    stops, paths = [], []
    for k, stop in enumerate(plan.get("stops") or [], 1):
        pos = stop.get("position") or [0.0, 0.0, 0.0]
        for p in (stop.get("carrier_path") or [])[1:-1]:
            route.append([p[0], p[1]])
        route.append([pos[0], pos[1]])
        stops.append({"k": k, "e": pos[0], "n": pos[1], "arrive": stop.get("arrive"),
                      "rovers": [r.get("rover") for r in stop.get("rovers") or []]})
        for r in stop.get("rovers") or []:
            if r.get("task") and r.get("target"):
                tasks.setdefault(str(r["task"]), list(r["target"]))
            path = r.get("path") or [r.get("from") or pos, r.get("target") or pos]  # collect: from -> stop
            paths.append({"rover": r.get("rover"), "path": [[p[0], p[1]] for p in path]})
    return {"kind": plan.get("kind"), "makespan": plan.get("makespan"), "route": route, "stops": stops,
            "paths": paths,
            "tasks": [{"id": tid, "e": p[0], "n": p[1], "u": p[2] if len(p) > 2 else 0.0}
                      for tid, p in sorted(tasks.items())]}


def frame(state: FleetState) -> dict[str, Any]:
    """The state of the run now (see the module docstring)."""
    legs = planned_legs(state.plan)
    vehicles = []
    for v in state.vehicles.values():
        e, n, u = v.enu if v.enu is not None else (None, None, None)
        vehicles.append({
            "id": v.id, "role": v.role, "state": "lost" if v.lost else v.state, "task": v.task,
            "e": _r(e), "n": _r(n), "u": _r(u), "battery": _r(v.battery_pct, 0),
            "battery_level": battery_level(state, v), "link": link_level(v),
            "ttg": _r(time_to_go(state, v, legs), 1),
        })
    return {
        "mission": state.mission_name, "T": _r(state.mission_time, 1), "phase": str(state.phase),
        "stop": state.stop_index, "stops": state.stop_count, "elapsed": _r(state.elapsed, 1),
        "planned": _r(state.planned, 1), "ttg": _r(mission_time_to_go(state), 1), "replans": state.replans,
        "operation": _operation(state),
        "vehicles": vehicles,
        "events": [{"T": _r(ev.mission_time, 1), "kind": ev.kind, "text": ev.text}
                   for ev in list(state.events)[-EVENTS_SHOWN:]],
    }


def _operation(state: FleetState) -> dict[str, Any] | None:
    """A long operation's progress: sorties out, back and planned, tasks done of all, each task's
    ``[work done s, duration s, rover, done]``, the sorties out (``out``: index, rover, status and
    tasks each), the plan's sorties not launched yet (``ahead``: index, rover, tasks, launch and
    pick-up stop, mission s to its take-off), and ``eta`` as ``T`` (mission s since the run
    started); None for any other run."""
    if state.operation is None:
        return None
    op = state.operation()
    eta = None if op.eta is None else state.mission_time - state.elapsed + op.eta
    return {"sorties_out": op.sorties_out, "sorties_back": op.sorties_back, "sorties": op.sorties_planned,
            "done": op.done, "tasks": {t: [w, d, r, done] for t, (w, d, r, done) in op.tasks.items()},
            "working": [t for t, *_rest in op.working()], "eta": _r(eta, 1),
            "out": [{"sortie": s.index, "rover": s.rover, "status": s.status, "tasks": list(s.tasks)}
                    for s in op.out],
            "ahead": [{"sortie": a.index, "rover": a.rover, "tasks": list(a.tasks),
                       "launch": [_r(a.launch[0]), _r(a.launch[1])],
                       "pickup": None if a.pickup is None else [_r(a.pickup[0]), _r(a.pickup[1])],
                       "in": _r(a.takeoff_in, 1)} for a in op.ahead]}


def teams_plan(teams: ShownTeams) -> dict[str, Any]:
    """Every team's plan layer (route, stops, rover paths, with its team and colour) and every
    team's tasks (each with the team that has it)."""
    layers, tasks = [], {}
    for t in teams.shown():
        layer = plan_layer(t.state)
        for task in layer.pop("tasks"):
            tasks[task["id"]] = task | {"team": t.team}
        layers.append({"team": t.team, "colour": t.colour, **layer})
    makespans = [x["makespan"] for x in layers if isinstance(x.get("makespan"), int | float)]
    kinds = {x["kind"] for x in layers if x.get("kind")}
    return {"kind": kinds.pop() if len(kinds) == 1 else (None if not kinds else "mixed"),
            "makespan": max(makespans) if makespans else None,
            "tasks": [tasks[k] for k in sorted(tasks)], "teams": layers}


def teams_frame(teams: ShownTeams) -> dict[str, Any]:
    """The run now, every team (see the module docstring)."""
    shown = teams.shown()
    if not shown:
        return {"mission": teams.mission_name, "T": None, "phase": "", "stop": 0, "stops": 0, "elapsed": None,
                "planned": None, "ttg": None, "replans": 0, "teams": [], "vehicles": [], "events": []}
    owner = {v.id: t.team for t, v in teams.vehicles()}
    team_docs, vehicles, frames = [], [], []
    for t in shown:
        f = frame(t.state)
        frames.append(f)
        T, ttg = f["T"], f["ttg"]
        team_docs.append({"team": t.team, "colour": t.colour, "phase": f["phase"], "stop": f["stop"],
                          "stops": f["stops"], "elapsed": f["elapsed"], "planned": f["planned"], "ttg": ttg,
                          "eta": None if ttg is None or T is None else _r(T + ttg, 1),
                          "replans": f["replans"]})
        vehicles += [v | {"team": t.team} for v in f["vehicles"] if owner.get(v["id"]) == t.team]
    events = [{"T": _r(ev.mission_time, 1), "kind": ev.kind, "text": ev.text, "team": t.team if t else None}
              for t, ev in teams.events(EVENTS_SHOWN)]
    if not teams.several:
        return frames[0] | {"teams": team_docs, "vehicles": vehicles, "events": events}
    ttgs = [d["ttg"] for d in team_docs if d["ttg"] is not None]
    phases = list(dict.fromkeys(d["phase"] for d in team_docs))
    return {"mission": teams.mission_name, "T": _r(teams.mission_time, 1), "phase": " · ".join(phases),
            "stop": 0, "stops": 0, "elapsed": None, "planned": None, "ttg": max(ttgs) if ttgs else None,
            "replans": sum(d["replans"] for d in team_docs), "teams": team_docs, "vehicles": vehicles,
            "events": events}


class Trails:
    """The last :data:`TRAIL_POINTS` positions (E, N) of every vehicle, a point per :data:`TRAIL_STEP` m."""

    def __init__(self, points: int = TRAIL_POINTS, step: float = TRAIL_STEP) -> None:
        self.points = points
        self.step = step
        self.trails: dict[str, deque[tuple[float, float]]] = {}

    def add(self, state: FleetState) -> None:
        for v in state.vehicles.values():
            self._add(v)

    def _add(self, v: VehicleState) -> None:
        if v.enu is None:
            return
        if v.role == "rover" and v.state in ON_DECK:  # riding on the carrier: no trail of its own
            self.trails.pop(v.id, None)
            return
        trail = self.trails.setdefault(v.id, deque(maxlen=self.points))
        p = (round(v.enu[0], 2), round(v.enu[1], 2))
        if not trail or math.dist(trail[-1], p) >= self.step:
            trail.append(p)

    def add_teams(self, teams: ShownTeams) -> None:
        """:meth:`add` for every vehicle every team shows."""
        for _, v in teams.vehicles():
            self._add(v)

    def to_json(self) -> dict[str, list[list[float]]]:
        return {vid: [list(p) for p in t] for vid, t in self.trails.items()}


__all__ = ["EVENTS_SHOWN", "TRAIL_POINTS", "Trails", "frame", "plan_layer", "teams_frame", "teams_plan"]
