"""A mission's teams (``carrier:`` is one team; ``carriers:`` one per carrier) and the planning
problem that shares its tasks or rovers between them (``planners.teams``)."""

from __future__ import annotations

from dataclasses import replace

from fleetctl.mission.model import Mission, TeamConfig
from planners.teams import TeamsProblem


def mission_teams(mission: Mission) -> tuple[TeamConfig, ...]:
    """Every carrier with the rover ids on its deck, in the order of the mission file."""
    return mission.teams or (TeamConfig(mission.carrier, mission.rovers.ids),)


def several_teams(mission: Mission) -> bool:
    return len(mission_teams(mission)) > 1


def teams_problem(mission: Mission, phase: str) -> TeamsProblem:
    """The deployment (``phase`` "deploy") or collection problem of every team: its own carrier,
    start, heading and deck, the mission's whole pool of tasks or rovers to collect."""
    problems = []
    for team in mission_teams(mission):
        own = replace(mission, carrier=team.carrier)  # the mission as if this carrier were its only one
        problems.append(replace(own.deploy_problem(), rovers=team.rovers) if phase == "deploy"
                        else own.collect_problem())
    return TeamsProblem(tuple(t.carrier.id for t in mission_teams(mission)), tuple(problems))
