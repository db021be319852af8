"""``deploy|run --team ID``: one team of a several-carrier mission, one controller per team.

(Not to be confused with :class:`fleetctl.run.teams.team_run.TeamRun`: one team's run *inside*
the controller that flies every team, :class:`~fleetctl.run.teams.coordinator.TeamsFlight`.)

Every controller computes the same allocation of the tasks to the teams (:func:`team_shares`:
the mission's deploy planner, its seed, the quick plan only, so the same file gives the same
shares everywhere) and flies its own share in a :class:`~fleetctl.run.crew.Crew` of one team
whose flight is :class:`TeamControllerRun`, an ordinary
:class:`~fleetctl.run.runner.TeamFlight` of :func:`~fleetctl.mission.teams.team_mission` (its carrier,
the rovers on its deck; the embedded simulator of ``connection: sim`` runs that team only). With
a bus, a :class:`~fleetctl.run.teams.link.TeamLink` coordinates it with the other teams'
controllers; when its own share is done the team stands by while another team may still hand
tasks over, and flies each handed-over batch as one more deployment round with the rovers left
on its deck.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fleetctl.bus.config import BusConfig
from fleetctl.journal import JOURNAL_NAME, read_journal
from fleetctl.mavlink.fleet import Fleet
from fleetctl.mission import Mission
from fleetctl.mission.teams import team_mission, team_of
from fleetctl.run.crew import Crew
from fleetctl.run.kinds import Ev
from fleetctl.run.lifecycle import RunOptions, RunOutcome
from fleetctl.run.rounds import NoMoreWork, WorkSource
from fleetctl.run.runner import TeamFlight
from fleetctl.run.sim import mission_uses_sim
from fleetctl.run.teams.link import TeamLink
from fleetctl.run.teams.rounds import LinkWork


@dataclass(frozen=True)
class TeamSpec:
    """Which team this controller flies, of which several-carrier mission, and how the tasks are shared."""

    team: str
    mission: Mission  # the whole mission (every team)
    shares: dict[str, list[str]]  # team -> its tasks (the shared allocation)
    prefix: str | None  # the mission's topic prefix P (None: no bus, no coordination)


def team_shares(mission: Mission, planner: str | None = None) -> dict[str, list[str]]:
    """The allocation every team's controller computes alike: team -> task ids (PlanningError
    and KeyError for an unknown planner go to the caller)."""
    from fleetctl.teams_plan import plan_for_teams
    from planners import DEPLOY_PLANNERS

    name = (planner.split(",")[0].strip() if planner else "") or mission.planner_for("deploy")
    quick = dataclasses.replace(mission, planner=dataclasses.replace(mission.planner, budget_ms=None))
    plan, _ = plan_for_teams(quick, False, DEPLOY_PLANNERS[name], name)
    return {tp.carrier: [leg.task for leg in tp.plan.legs() if leg.task is not None] for tp in plan.teams}


def team_bus_config(config: BusConfig | None, team: str) -> BusConfig | None:
    """The team controller's bus: prefix ``P/teams/<team>`` (its status is the team's presence),
    its own client id."""
    if config is None:
        return None
    cid = f"{config.client_id}-{team}" if config.client_id else None
    return dataclasses.replace(config, topic_prefix=f"{config.topic_prefix}/teams/{team}", client_id=cid)


def prepare_team(mission: Mission, team: str, planner: str | None,
                 config: BusConfig | None) -> tuple[Mission, TeamSpec, BusConfig | None]:
    """The one-team mission to fly, the spec of the coordination, the team's bus settings."""
    team_of(mission, team)  # MissionError naming the carriers
    shares = team_shares(mission, planner)
    own = team_mission(mission, team, tasks=shares.get(team, []))
    spec = TeamSpec(team, mission, shares, config.topic_prefix if config is not None else None)
    return own, spec, team_bus_config(config, team)


class TeamControllerRun(TeamFlight):
    """A :class:`TeamFlight` of one team's share with a :class:`TeamLink` (see the module docstring)."""

    def __init__(self, crew: Crew[Any], spec: TeamSpec) -> None:
        super().__init__(crew)
        mission, opts = self.mission, self.opts
        self.spec = spec
        rovers = team_of(spec.mission, spec.team).rovers
        self.link: TeamLink | None = None
        if spec.prefix is not None:
            embedded = opts.sim is None and opts.endpoints is None and mission_uses_sim(mission)
            vehicles = "sim" if embedded else "real"
            self.link = TeamLink(spec.mission, spec.team, spec.shares, spec.prefix, vehicles, rovers)
            if opts.resume is not None:  # re-joins the other teams with the claims it held
                self.link.resume(read_journal(Path(opts.resume.run_dir) / JOURNAL_NAME))

    def _start_bus(self) -> Any:
        from fleetctl.bus.client import start_bus

        link = self.link
        prepare: Callable[[Any], None] | None = link.prepare if link is not None else None
        bus = start_bus(self.mission, self.opts.mqtt, self.journal, self.state, self.opts.view,
                        prepare=prepare)
        if link is not None and bus is not None:
            link.start(self.state, self.journal.write)
        elif link is not None:  # the bus is off (a bad setting was reported): no coordination
            self.link = None
        if self.link is None:
            share = ", ".join(t.id for t in self.mission.tasks) or "none"
            self.state.event(Ev.TEAM_ALONE, f"team {self.spec.team}: no MQTT bus, so no coordination with "
                             f"the other teams: flying this team's share ({share}) only; its tasks are not "
                             "handed over if it fails", None)
        return bus

    async def connected(self, fleet: Fleet) -> None:
        await super().connected(fleet)
        if self.link is not None and self.executor is not None:
            self.link.attach_executor(self.executor)

    def _work_source(self) -> WorkSource:
        """With a link, the team stands by after its share for tasks the other teams hand over."""
        if self.link is None or self.executor is None:
            return NoMoreWork(self.spec.team, flies_empty_share=False)
        return LinkWork(self.link, self.executor.board)

    async def end(self) -> dict[str, Any]:
        if self.link is not None:
            await self.link.close()
            with contextlib.suppress(OSError):  # the records must never stop the way out
                await asyncio.to_thread(self.journal.write_json, "team.json", self.link.stats())
        return await super().end()


async def fly_team_controller(mission: Mission, command: str, spec: TeamSpec,
                              opts: RunOptions) -> RunOutcome:
    """:func:`fleetctl.run.flight.fly` for one team (``mission``: the team's own, from
    :func:`prepare_team`)."""
    return await Crew(mission, command, opts, lambda crew: TeamControllerRun(crew, spec)).fly()


__all__ = ["TeamControllerRun", "TeamSpec", "fly_team_controller", "prepare_team", "team_bus_config",
           "team_shares"]
