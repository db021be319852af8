"""A mission's teams (``carrier:`` is one team; ``carriers:`` one per carrier) and the planning
problem that shares its tasks or rovers between them (``planners.teams``)."""

from __future__ import annotations

import copy
from collections.abc import Iterable
from dataclasses import replace
from typing import Any

from fleetctl.mission.flight import descent
from fleetctl.mission.model import CarrierConfig, Mission, MissionError, RoverUnit, TeamConfig
from planners.teams import TeamsProblem


def mission_teams(mission: Mission) -> tuple[TeamConfig, ...]:
    """Every carrier with the rover ids on its deck, in the order of the mission file."""
    return mission.teams or (TeamConfig(mission.carrier, mission.rovers.ids),)


def own_mission(mission: Mission, carrier: CarrierConfig) -> Mission:
    """The mission as if ``carrier`` were its only one. A touch-down term the mission file does not
    give was worked out for the first carrier's deck (``carrier.deck_height``): it is moved to
    this carrier's descent, so a team whose deck stands higher or lower plans its own landings."""
    own = replace(mission, carrier=carrier)
    r = mission.rovers
    if r.handling_given[1] or carrier.deck_height == mission.carrier.deck_height:
        return own
    shift = (descent(carrier.deck_height) - descent(mission.carrier.deck_height)) / r.land_speed
    return replace(own, rovers=replace(r, land_time=r.land_time + shift))


def several_teams(mission: Mission) -> bool:
    return len(mission_teams(mission)) > 1


def teams_problem(mission: Mission, phase: str) -> TeamsProblem:
    """The deployment (``phase`` "deploy") or collection problem of every team: its own carrier,
    start, heading and deck, the mission's whole pool of tasks or rovers to collect."""
    problems = []
    for team in mission_teams(mission):
        own = own_mission(mission, team.carrier)
        problems.append(replace(own.deploy_problem(), rovers=team.rovers) if phase == "deploy"
                        else own.collect_problem())
    return TeamsProblem(tuple(t.carrier.id for t in mission_teams(mission)), tuple(problems))


def team_of(mission: Mission, team_id: str) -> TeamConfig:
    """The team whose carrier is ``team_id`` (MissionError naming the carriers if none is)."""
    for team in mission_teams(mission):
        if team.carrier.id == team_id:
            return team
    ids = ", ".join(t.carrier.id for t in mission_teams(mission))
    raise MissionError(f"{mission.path or mission.name}: no carrier {team_id!r} in the mission "
                       f"(carriers: {ids})")


def team_mission(mission: Mission, team_id: str, tasks: Iterable[str] | None = None,
                 rovers: Iterable[str] | None = None) -> Mission:
    """The mission as one team flies it: that carrier, the rovers ``rovers`` (default: the ones on
    its deck; a collection may give it rovers of other decks), the tasks ``tasks`` (ids; default
    every task) and the collection entries of its rovers. ``raw`` is rewritten to the one-team
    form (``carrier:`` and ``rovers.units``), so whatever reads the file as written (the embedded
    simulator, the run folder's records) sees this team only."""
    team = team_of(mission, team_id)
    ids = tuple(team.rovers if rovers is None else rovers)
    by_id = {u.id: u for u in mission.rovers.units}
    missing = [r for r in ids if r not in by_id]
    if missing:
        raise MissionError(f"{mission.path or mission.name}: no rover {missing[0]!r} in the mission")
    wanted = None if tasks is None else set(tasks)
    own_tasks = tuple(t for t in mission.tasks if wanted is None or t.id in wanted)
    collection = (None if mission.collection is None
                  else tuple(r for r in mission.collection if r.id in ids))
    units = tuple(by_id[r] for r in ids)
    ours = {team_id} | set(ids)  # a simulator of this team alone knows only its own vehicles' faults
    faults = tuple(f for f in mission.sim.faults if f.vehicle in ours or f.vehicle is None)
    sim = replace(mission.sim, faults=faults)
    own = own_mission(mission, team.carrier)
    return replace(own, rovers=replace(own.rovers, units=units),
                   tasks=own_tasks, collection=collection, teams=(), sim=sim,
                   raw=_one_team_raw(mission.raw, team_id, units))


def _one_team_raw(raw: dict[str, Any], team_id: str, units: tuple[RoverUnit, ...]) -> dict[str, Any]:
    d = copy.deepcopy(raw)
    if "carriers" in d:
        entry = next(c for c in d.pop("carriers") if c.get("id") == team_id)
        d["carrier"] = {k: v for k, v in entry.items() if k not in ("fleet", "units")}
    rovers = {k: v for k, v in dict(d.get("rovers") or {}).items() if k not in ("fleet", "units")}
    rovers["units"] = [_unit_raw(u) for u in units]
    d["rovers"] = rovers
    sim = d.get("sim")
    if isinstance(sim, dict) and isinstance(sim.get("faults"), list):  # this team's vehicles' faults only
        ours = {team_id} | {u.id for u in units}
        sim["faults"] = [f for f in sim["faults"] if not isinstance(f, dict) or f.get("vehicle") in ours
                         or f.get("vehicle") is None]
    return d


def _unit_raw(u: RoverUnit) -> dict[str, Any]:
    return {"id": u.id, "sysid": u.sysid} | ({} if u.connection is None else {"connection": u.connection})
