"""A mission's teams (``carrier:`` is one team; ``carriers:`` one per carrier) and the planning
problem that shares its tasks or rovers between them (``planners.teams``)."""

from __future__ import annotations

from dataclasses import replace

from fleetctl.geo import compass_to_math
from fleetctl.mission.model import Mission, TeamConfig
from planners.problem import DeployProblem
from planners.teams import TeamsProblem


def mission_teams(mission: Mission) -> tuple[TeamConfig, ...]:
    """Every carrier with the rover ids on its deck, in the order of the mission file."""
    return mission.teams or (TeamConfig(mission.carrier, mission.rovers.ids),)


def several_teams(mission: Mission) -> bool:
    return len(mission_teams(mission)) > 1


def teams_problem(mission: Mission, phase: str) -> TeamsProblem:
    """The deployment (``phase`` "deploy") or collection problem of every team: its own carrier,
    start, heading and deck, the mission's whole pool of tasks or rovers to collect."""
    base = mission.deploy_problem() if phase == "deploy" else mission.collect_problem()
    problems = []
    for team in mission_teams(mission):
        c = team.carrier
        p = replace(base, carrier=c.spec(), start=(c.position[0], c.position[1], 0.0),
                    heading=compass_to_math(c.heading_deg))
        problems.append(replace(p, rovers=team.rovers) if isinstance(p, DeployProblem) else p)
    return TeamsProblem(tuple(t.carrier.id for t in mission_teams(mission)), tuple(problems))
