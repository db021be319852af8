"""A deployment flown in rounds: the first round flies the mission's tasks, then a
:class:`WorkSource` may hand the deployment more tasks, each batch one more round on the same
:class:`~fleetctl.run.task_board.TaskBoard` with the rovers left on the deck.

:meth:`fleetctl.run.runner.TeamFlight._deploy` is the one loop; the source says whether there is more
work, and how a round that leaves tasks unserved is judged (:class:`Unserved`). A one-carrier run
has no source of more work (:data:`NO_MORE_WORK`); the several-carrier sources are in
:mod:`fleetctl.run.teams.rounds`.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Protocol

from fleetctl.run.results import PhaseResult
from planners.core.problem import Task


class Unserved(StrEnum):
    """What becomes of a deployment round that leaves tasks unserved."""

    # judged at once, as a one-carrier deployment is: ``deploy`` fails (ExecutionError), ``run``
    # with rovers launched goes on (to collect them); a ``--team`` controller's peers then take
    # its tasks over through the link
    FAIL = "fail"
    # the round's result goes back to the work source, which re-allocates what it left (to this
    # team or another); only the last round's result is judged
    HAND_BACK = "hand back"


class WorkSource(Protocol):
    """Who hands a deployment more rounds."""

    @property
    def name(self) -> str:
        """Who the work comes from, for the records (a team's id)."""
        ...

    @property
    def unserved(self) -> Unserved:
        """How a round that leaves tasks unserved is judged."""
        ...

    @property
    def flies_empty_share(self) -> bool:
        """Whether the first round is flown when the mission has no task (False: the deployment
        stands by for handed-over work at once)."""
        ...

    async def next_round(self, last: PhaseResult) -> list[Task] | None:
        """After a round (``last``: its result): the tasks to put on the board for one more round
        (``[]``: a round for tasks the source gave as a task change), or None: the deployment is over."""
        ...


@dataclass(frozen=True)
class NoMoreWork:
    """A deployment of one round (a one-carrier run; a team flown alone)."""

    name: str = ""
    unserved: Unserved = Unserved.FAIL
    flies_empty_share: bool = True

    async def next_round(self, last: PhaseResult) -> list[Task] | None:
        return None


NO_MORE_WORK = NoMoreWork()


@dataclass
class DeployRounds:
    """What the rounds of a deployment flew so far."""

    flown: int = 0  # rounds flown (1 + the rounds for handed-over tasks; 0: an empty share stood by)
    first_planned: float | None = None  # the first round's planned makespan (mission s)

    def count(self, result: PhaseResult) -> None:
        self.flown += 1
        if self.flown == 1:
            self.first_planned = result.planned


__all__ = ["NO_MORE_WORK", "DeployRounds", "NoMoreWork", "Unserved", "WorkSource"]
