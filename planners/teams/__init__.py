"""Several carriers on one mission (docs/teams.md): share the tasks (deployment) or the rovers
(collection) between teams, each team planned by today's planners; the nearest-carrier baseline
and a lower bound. Pure maths, no I/O.

The names below load their module on first use, so that a mission's teams (``TeamsProblem``) cost
no planner imports until something is planned.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from planners.teams.allocation import plan_teams, plan_teams_nearest
    from planners.teams.lower_bound import teams_lower_bound
    from planners.teams.plan import TeamPlan, TeamsPlan
    from planners.teams.problem import TeamsProblem

_HOME = {"plan_teams": "allocation", "plan_teams_nearest": "allocation", "teams_lower_bound": "lower_bound",
         "TeamPlan": "plan", "TeamsPlan": "plan", "TeamsProblem": "problem"}

__all__ = ["TeamPlan", "TeamsPlan", "TeamsProblem", "plan_teams", "plan_teams_nearest", "teams_lower_bound"]


def __getattr__(name: str) -> Any:
    """A name of ``__all__`` from its module, imported on first use (PEP 562)."""
    home = _HOME.get(name)
    if home is None:
        raise AttributeError(f"module 'planners.teams' has no attribute {name!r}")
    return getattr(importlib.import_module(f"planners.teams.{home}"), name)
