"""A plan for several teams: one ordinary ``Plan`` per carrier, and its JSON (docs/teams.md).

The JSON keeps schema ``fleetctl.plan/1``: ``teams`` replaces the one-carrier ``carrier`` and
``stops`` keys; each team's stops and rover entries are those of a one-carrier plan.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from planners.core.plan import PLAN_SCHEMA, Plan


@dataclass
class TeamPlan:
    carrier: str
    plan: Plan


@dataclass
class TeamsPlan:
    """``teams`` in mission order (a team without work has a plan without stops)."""

    kind: Literal["deploy", "collect"]
    planner: str  # each team's planner
    allocation: str  # how the pool was shared: "search" or "nearest" (the baseline)
    teams: list[TeamPlan]
    compute_ms: float = 0.0
    baseline_makespan: float | None = None  # the nearest-carrier allocation's, when it was computed
    notes: list[str] = field(default_factory=list)

    @property
    def makespan(self) -> float:
        """The mission's makespan: the latest team's."""
        return max((t.plan.makespan for t in self.teams), default=0.0)

    def team(self, carrier: str) -> Plan:
        return next(t.plan for t in self.teams if t.carrier == carrier)

    def to_json(self) -> dict[str, Any]:
        teams = []
        for t in self.teams:
            one = t.plan.to_json()
            teams.append({"carrier": t.carrier, "start": one["carrier"]["start"],
                          "heading": one["carrier"]["heading"], "stops": one["stops"],
                          "makespan": one["makespan"], "carrier_distance": one["carrier_distance"],
                          **({"time_model": one["time_model"]} if "time_model" in one else {})})
        return {"schema": PLAN_SCHEMA, "kind": self.kind, "planner": self.planner,
                "allocation": self.allocation, "teams": teams,
                "makespan": round(float(self.makespan), 6), "compute_ms": round(self.compute_ms, 3)}
