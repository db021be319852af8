"""One team's run in a run of several teams: a :class:`~fleetctl.run.crew.Crew` of the team's
mission (:func:`fleetctl.mission.teams.team_mission`) whose flight, :class:`TeamRun`, is a
:class:`~fleetctl.run.runner.TeamFlight` with what a run of several teams adds: after its
deployment it may be handed tasks of another team and fly further rounds, and it keeps the
mission-clock times its tasks were reached and its rovers loaded (the teams' common clock).

Flown alone (:func:`fly_team`, ``coordinator`` None) it is exactly a one-team run of its share.
(The ``--team`` controller, one controller per team coordinating over MQTT, is another class:
:class:`fleetctl.run.teams.own_controller.TeamControllerRun`.)"""

from __future__ import annotations

import asyncio
from collections.abc import Iterable
from typing import Any

from fleetctl.aio import cancel_and_wait
from fleetctl.mission import Mission
from fleetctl.mission.teams import team_mission
from fleetctl.run.crew import Crew
from fleetctl.run.lifecycle import RunOptions, RunOutcome
from fleetctl.run.results import PhaseResult
from fleetctl.run.rounds import NO_MORE_WORK, WorkSource
from fleetctl.run.runner import TeamFlight
from fleetctl.run.teams.rounds import Coordinator, CoordinatorWork

PLAN_WAIT = 120.0  # wall s a collection scenario's batteries are held at most, waiting for the first plan


class TeamRun(TeamFlight):
    """A team's flight in a run of several teams (see the module docstring)."""

    def __init__(self, crew: Crew[Any], team: str, coordinator: Coordinator | None = None,
                 t0: float | None = None) -> None:
        super().__init__(crew)
        if t0 is not None:  # T+ of the run of every team
            self.state.count_from(t0)
        self.team = team
        self.coordinator = coordinator
        self.started_at: float | None = None  # mission clock: its carrier first started
        self.reached_at: dict[str, float] = {}  # task -> mission clock
        self.loaded_at: dict[str, float] = {}  # rover -> mission clock
        self.collect_started: float | None = None
        self.collect_ended: float | None = None
        self._release: asyncio.Task[None] | None = None  # lets a collection scenario's batteries drain

    def _work_source(self) -> WorkSource:
        """After each deployment round the coordinator may hand the team more tasks (one more round)."""
        return NO_MORE_WORK if self.coordinator is None else CoordinatorWork(self.coordinator, self.team)

    def _round_flown(self, result: PhaseResult) -> None:
        self._note_reached()

    def _note_reached(self) -> None:
        phase = self.executor.deploy_phase if self.executor is not None else None
        if phase is None or phase.t0 is None:
            return
        if self.started_at is None:
            self.started_at = phase.t0
        for tid, flown in phase.board.reached().items():
            self.reached_at.setdefault(tid, phase.t0 + flown)

    def _release_batteries(self) -> None:
        """A ``collection:`` scenario on the simulated fleet: the batteries are held at the
        scenario's ranges until the team's first collection plan is made (sharing and planning
        several teams takes seconds of wall time, minutes of hover at a high speedup), then
        drain."""
        if self.sim is None or self.command != "collect" or not self.mission.collection:
            return
        self._release = asyncio.create_task(self._release_after_plan(), name=f"team {self.team}: batteries")

    async def _release_after_plan(self) -> None:
        try:
            async with asyncio.timeout(PLAN_WAIT):
                while not self._planned_collection():
                    await asyncio.sleep(0.02)
        except TimeoutError:
            pass
        finally:
            self.session.pin_scenario_batteries(False)

    def _planned_collection(self) -> bool:
        phase = self.executor.collect_phase if self.executor is not None else None
        return phase is not None and phase.plan is not None

    async def end(self) -> dict[str, Any]:
        release, self._release = self._release, None
        await cancel_and_wait(release)  # lets the batteries drain if the collection never got to a plan
        return await super().end()

    async def _collect(self) -> None:
        try:
            await super()._collect()
        finally:
            phase = self.executor.collect_phase if self.executor is not None else None
            if phase is not None and phase.t0 is not None:
                self.collect_started = phase.t0
                self.loaded_at = {r: phase.t0 + t for r, t in phase.board.loaded_at.items()}
                if phase.result.flown is not None:  # the one-team measure: up to the last load
                    self.collect_ended = phase.t0 + phase.result.flown


async def fly_team(
    mission: Mission,
    team_id: str,
    command: str,
    *,
    tasks: Iterable[str] | None = None,
    rovers: Iterable[str] | None = None,
    coordinator: Coordinator | None = None,
    **options: Any,
) -> RunOutcome:
    """Fly one team of a several-carrier mission alone (its own simulated fleet for ``connection:
    sim``, its own links): ``tasks`` its share of the tasks (default: every task), ``rovers`` the
    rovers it flies or collects (default: its deck). ``coordinator`` (e.g. one speaking to the other
    teams' controllers) is asked after each deployment round for tasks handed to it. Options as
    :func:`fleetctl.run.flight.execute`."""
    own = team_mission(mission, team_id, tasks=tasks, rovers=rovers)
    return await team_crew(own, command, RunOptions(**options), team_id, coordinator).fly()


def team_crew(mission: Mission, command: str, opts: RunOptions, team: str,
              coordinator: Coordinator | None = None, t0: float | None = None) -> Crew[TeamRun]:
    """The crew of one team's run (:class:`TeamRun`) of its own ``mission``."""
    return Crew(mission, command, opts, lambda crew: TeamRun(crew, team, coordinator, t0))


__all__ = ["Coordinator", "TeamRun", "fly_team", "team_crew"]
