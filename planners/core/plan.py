"""Plan types and their JSON form (docs/plan-json.md)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from planners.core.problem import Vec3

PLAN_SCHEMA = "fleetctl.plan/1"

# m: builders put a stop closer than this to the previous one on it (when its rovers reach): a hop of
# millimetres has an arbitrary heading once coordinates are rounded for JSON, and turning costs time
SNAP = 1e-2


@dataclass
class RoverLeg:
    """One rover's flight: deploy (stop → task) or collect (rover's position → meeting point)."""

    rover: str
    path: list[Vec3]
    arrive: float = 0.0
    task: str | None = None  # deployment only

    @property
    def start(self) -> Vec3:
        return self.path[0]

    @property
    def end(self) -> Vec3:
        return self.path[-1]


@dataclass
class Stop:
    position: Vec3
    carrier_path: list[Vec3]  # from the previous stop (or the start) to this stop
    rovers: list[RoverLeg]
    arrive: float = 0.0
    depart: float = 0.0


@dataclass
class Plan:
    kind: Literal["deploy", "collect"]
    planner: str
    start: Vec3
    heading: float
    stops: list[Stop]
    makespan: float = 0.0
    carrier_distance: float = 0.0
    compute_ms: float = 0.0
    notes: list[str] = field(default_factory=list)
    # The time model's per-stop and per-flight terms the times were computed with (set by
    # ``planners.core.timing.retime``; docs/time-model.md): takeoff_time, land_time, rover_fixed_time,
    # vertex_stops.
    time_model: dict[str, float | bool] | None = None
    # Roadmap planners (ch. 6) attach their graph for drawing: an object with ``xy`` ((N, 2)
    # node coordinates) and ``edges()`` ((E, 2) node index pairs). Not part of the JSON.
    roadmap: Any = field(default=None, repr=False, compare=False)

    def legs(self) -> list[RoverLeg]:
        return [leg for stop in self.stops for leg in stop.rovers]

    def to_json(self) -> dict[str, Any]:
        stops = []
        for s in self.stops:
            rovers: list[dict[str, Any]] = []
            for leg in s.rovers:
                if self.kind == "deploy":
                    rovers.append({"rover": leg.rover, "task": leg.task, "target": point_json(leg.end),
                                   "path": [point_json(p) for p in leg.path], "arrive": _t(leg.arrive)})
                else:
                    rovers.append({"rover": leg.rover, "from": point_json(leg.start),
                                   "path": [point_json(p) for p in leg.path], "arrive": _t(leg.arrive)})
            stops.append({"position": point_json(s.position), "arrive": _t(s.arrive), "depart": _t(s.depart),
                          "carrier_path": [point_json(p) for p in s.carrier_path], "rovers": rovers})
        return {
            "schema": PLAN_SCHEMA,
            "kind": self.kind,
            "planner": self.planner,
            "carrier": {"start": point_json(self.start), "heading": round(self.heading, 6)},
            "stops": stops,
            "makespan": _t(self.makespan),
            "carrier_distance": round(self.carrier_distance, 4),
            "compute_ms": round(self.compute_ms, 3),
            **({"time_model": dict(self.time_model)} if self.time_model is not None else {}),
        }


# decimals of a position in the plan JSON: times are recomputed from positions, and the heading of
# a hop of a centimetre moves by 1e-4 rad when its ends are rounded to 6 decimals (seconds of turn
# at a slow carrier's turn rate, off by 1e-4 s); at 9 it moves by 1e-7 rad
POSITION_DECIMALS = 9


def point_json(p: Vec3) -> list[float]:
    """A position as the plan JSON writes it (``POSITION_DECIMALS``)."""
    return [round(float(c), POSITION_DECIMALS) for c in p]


def _t(t: float) -> float:
    return round(float(t), 6)
