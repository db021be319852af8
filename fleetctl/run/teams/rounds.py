"""Where a team of a several-carrier mission gets its further deployment rounds from: the two
:class:`~fleetctl.run.rounds.WorkSource` of the teams (the rounds loop is
:meth:`fleetctl.run.runner.TeamFlight._deploy`).

* :class:`CoordinatorWork` - a team inside the controller that flies every team
  (:class:`~fleetctl.run.teams.team_run.TeamRun`): the run of every team is asked after each round;
  a round that leaves tasks unserved is handed back to it, which re-allocates those tasks.
* :class:`LinkWork` - a ``--team`` controller
  (:class:`~fleetctl.run.teams.own_controller.TeamControllerRun`): tasks the other teams'
  controllers leave come through its :class:`~fleetctl.run.teams.link.TeamLink` as task changes;
  a round that leaves tasks unserved is judged at once (``deploy`` fails), and the peers take
  them over through their links.
"""

from __future__ import annotations

import asyncio
from typing import Protocol

from fleetctl.run.results import PhaseResult
from fleetctl.run.rounds import Unserved
from fleetctl.run.task_board import TaskBoard
from fleetctl.run.teams.link import STANDBY_POLL, TeamLink
from planners.core.problem import Task


class Coordinator(Protocol):
    """What a team's run asks the run of every team (:class:`fleetctl.run.teams.coordinator.TeamsFlight`).

    ``more_work`` is awaited after each deployment round with its result (``tasks_unserved``: what
    the team could not serve); it returns the tasks handed to the team (one more round), or ``[]``
    when its deployment is over. Tasks handed while the team deploys may instead go in as a task
    change: ``run.executor.submit_task_change(add=..., remove=[], source="team <from>")``."""

    async def more_work(self, team: str, result: PhaseResult) -> list[Task]: ...


class CoordinatorWork:
    """Further rounds from the run of every team (see the module docstring)."""

    unserved = Unserved.HAND_BACK
    flies_empty_share = True  # a team given no task flies its (empty) round, then asks for work

    def __init__(self, coordinator: Coordinator, team: str) -> None:
        self.coordinator = coordinator
        self.name = team

    async def next_round(self, last: PhaseResult) -> list[Task] | None:
        return await self.coordinator.more_work(self.name, last) or None


class LinkWork:
    """Further rounds from the other teams' controllers, through the link (see the module docstring)."""

    unserved = Unserved.FAIL
    flies_empty_share = False  # a team given no task stands by at once

    def __init__(self, link: TeamLink, board: TaskBoard) -> None:
        self.link, self.board = link, board
        self.name = link.team
        self.entries_at_round: int | None = None  # tasks on the board when the last handed-over round began

    def took_nothing(self) -> bool:
        """The last handed-over round put no task on the board (its deployment refused them)."""
        return self.entries_at_round is not None and len(self.board.entries) == self.entries_at_round

    async def next_round(self, last: PhaseResult) -> list[Task] | None:
        if self.took_nothing():  # what was handed over was refused: look again in a while
            await asyncio.sleep(STANDBY_POLL)
        if not await self.link.wait_for_work():
            return None
        self.entries_at_round = len(self.board.entries)
        return []  # the handed-over tasks wait as a task change the round takes in


__all__ = ["Coordinator", "CoordinatorWork", "LinkWork"]
