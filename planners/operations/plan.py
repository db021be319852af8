"""The schedule of a long operation and its plan JSON (docs/plan-json.md, "An operation plan")."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from planners.core.plan import PLAN_SCHEMA, point_json
from planners.core.problem import Vec3


@dataclass
class Visit:
    """A task worked in a sortie: the rover arrives, works ``end − arrive`` s and leaves (a rover
    may wait at its last task before flying back: landed at a ground task, that costs no battery)."""

    task: str
    position: Vec3
    arrive: float
    end: float
    leave: float
    ground: bool


@dataclass
class Sortie:
    """One rover's flight from a launch stop through its tasks to a pick-up stop.

    ``takeoff``: the start command (the rover is in the air from then on); ``depart``: clear of the
    deck, its line to the first task starts; ``meet``: at the approach point over the pick-up stop;
    ``landed``: touched down on the deck; ``aboard``: loaded."""

    rover: str
    launch_stop: int
    takeoff: float
    depart: float
    visits: list[Visit]
    pickup_stop: int = -1
    meet: float = 0.0
    landed: float = 0.0
    aboard: float = 0.0
    air_time: float = 0.0
    battery_start: float = 1.0  # fraction of a full battery at take-off
    battery_left: float = 1.0  # at touch-down


@dataclass
class OpStop:
    """A carrier stop: it arrives, picks up its returning rovers (``loaded``), launches fresh ones
    and leaves (``depart``)."""

    position: Vec3
    carrier_path: list[Vec3]
    arrive: float
    loaded: float
    depart: float
    pickups: list[str] = field(default_factory=list)
    launches: list[str] = field(default_factory=list)


@dataclass
class Swap:
    rover: str
    start: float
    end: float


@dataclass
class OperationPlan:
    planner: str
    start: Vec3
    heading: float
    stops: list[OpStop]
    sorties: list[Sortie]
    swaps: list[Swap]
    makespan: float = 0.0
    carrier_distance: float = 0.0
    compute_ms: float = 0.0
    time_model: dict[str, float | bool] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    called_back: dict[str, list[str]] = field(default_factory=dict)  # a replan's rover -> tasks dropped
    recovery: bool = False  # a replan that only brings the rovers in the air back (reserve given up)

    kind = "operation"

    def to_json(self) -> dict[str, Any]:
        return {
            "schema": PLAN_SCHEMA,
            "kind": "operation",
            "planner": self.planner,
            "carrier": {"start": point_json(self.start), "heading": round(self.heading, 6)},
            "stops": [_stop_json(s, self.sorties) for s in self.stops],
            "sorties": [_sortie_json(k, s) for k, s in enumerate(self.sorties)],
            "rovers": self.timelines(),
            "tasks": {v.task: {"rover": s.rover, "sortie": k, "start": _t(v.arrive), "end": _t(v.end)}
                      for k, s in enumerate(self.sorties) for v in s.visits if v.task},
            "makespan": _t(self.makespan),
            "carrier_distance": round(self.carrier_distance, 4),
            "compute_ms": round(self.compute_ms, 3),
            "time_model": dict(self.time_model),
            "called_back": {r: list(ts) for r, ts in sorted(self.called_back.items())},
            "recovery": self.recovery,
        }

    def timelines(self) -> dict[str, list[dict[str, Any]]]:
        """Per rover, in time order: its sorties (take-off to aboard) and battery swaps."""
        out: dict[str, list[tuple[float, dict[str, Any]]]] = {}
        for k, s in enumerate(self.sorties):
            out.setdefault(s.rover, []).append(
                (s.takeoff, {"kind": "sortie", "sortie": k, "from": _t(s.takeoff), "to": _t(s.aboard)}))
        for w in self.swaps:
            row = {"kind": "swap", "from": _t(w.start), "to": _t(w.end)}
            out.setdefault(w.rover, []).append((w.start, row))
        return {r: [e for _, e in sorted(rows, key=lambda x: x[0])] for r, rows in sorted(out.items())}


def _stop_json(s: OpStop, sorties: list[Sortie]) -> dict[str, Any]:
    return {"position": point_json(s.position), "arrive": _t(s.arrive), "loaded": _t(s.loaded),
            "depart": _t(s.depart), "carrier_path": [point_json(p) for p in s.carrier_path],
            "pickups": list(s.pickups), "launches": list(s.launches)}


def _sortie_json(k: int, s: Sortie) -> dict[str, Any]:
    return {"id": k, "rover": s.rover, "launch_stop": s.launch_stop, "pickup_stop": s.pickup_stop,
            "takeoff": _t(s.takeoff), "depart": _t(s.depart),
            "visits": [{"task": v.task, "position": point_json(v.position), "arrive": _t(v.arrive),
                        "end": _t(v.end), "leave": _t(v.leave), "work": "ground" if v.ground else "hover"}
                       for v in s.visits],
            "meet": _t(s.meet), "landed": _t(s.landed), "aboard": _t(s.aboard),
            "air_time": _t(s.air_time), "battery_start": round(s.battery_start, 6),
            "battery_left": round(s.battery_left, 6)}


def _t(t: float) -> float:
    return round(float(t), 6)
