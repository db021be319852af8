"""The work sources of a deployment flown in rounds (fleetctl.run.rounds, fleetctl.run.teams.rounds):
what each hands the rounds loop (Run._deploy) and how it judges a round that leaves tasks unserved.
The loop itself flies in the teams' flight tests (handed-over rounds in one controller, and
``--team`` controllers over MQTT)."""

from __future__ import annotations

import time
from pathlib import Path

from fleetctl.mission.teams import team_mission
from fleetctl.run.results import PhaseResult
from fleetctl.run.rounds import NO_MORE_WORK, DeployRounds, Unserved
from fleetctl.run.task_board import TaskBoard
from fleetctl.run.teams.link import STANDBY_POLL, TeamLink
from fleetctl.run.teams.own_controller import team_shares
from fleetctl.run.teams.rounds import CoordinatorWork, LinkWork
from planners.core.problem import Task
from tests.run.teams.teams_helpers import TWO_TEAMS, mission_from


def test_the_rounds_keep_the_first_plan_and_count_every_round() -> None:
    rounds = DeployRounds()
    rounds.count(PhaseResult("deploy", planned=42.0))
    rounds.count(PhaseResult("deploy", planned=7.0))
    assert (rounds.flown, rounds.first_planned) == (2, 42.0)


async def test_a_one_carrier_run_flies_one_round_judged_at_once() -> None:
    assert NO_MORE_WORK.unserved is Unserved.FAIL and NO_MORE_WORK.flies_empty_share
    assert await NO_MORE_WORK.next_round(PhaseResult("deploy")) is None


class OneBatch:
    """A coordinator that hands one batch over, then ends the deployment (Coordinator protocol)."""

    def __init__(self, batch: list[Task]) -> None:
        self.batches = [batch]
        self.asked: list[tuple[str, list[str]]] = []

    async def more_work(self, team: str, result: PhaseResult) -> list[Task]:
        self.asked.append((team, result.tasks_unserved))
        return self.batches.pop() if self.batches else []


async def test_the_coordinator_is_handed_each_round_and_its_batches_are_the_rounds() -> None:
    batch = [Task("x", (1.0, 2.0, 3.0))]
    coordinator = OneBatch(batch)
    work = CoordinatorWork(coordinator, "c1")
    assert work.unserved is Unserved.HAND_BACK and work.flies_empty_share
    assert await work.next_round(PhaseResult("deploy", tasks_unserved=["t1"])) == batch
    assert await work.next_round(PhaseResult("deploy")) is None  # [] from it: the deployment is over
    assert coordinator.asked == [("c1", ["t1"]), ("c1", [])]


def _link(tmp_path: Path) -> tuple[TeamLink, TaskBoard]:
    full = mission_from(TWO_TEAMS, tmp_path)
    shares = team_shares(full)
    own = team_mission(full, "c1", tasks=shares["c1"])
    link = TeamLink(full, "c1", shares, "test/rounds", "sim", [u.id for u in own.rovers.units])
    return link, TaskBoard.of(own.tasks)


async def test_the_link_ends_the_rounds_when_no_team_may_hand_work_over(tmp_path: Path) -> None:
    link, board = _link(tmp_path)
    work = LinkWork(link, board)
    assert work.unserved is Unserved.FAIL and not work.flies_empty_share
    assert await work.next_round(PhaseResult("deploy")) is None  # no peer ever seen online


async def test_a_handed_over_round_that_took_nothing_waits_before_the_next(tmp_path: Path) -> None:
    link, board = _link(tmp_path)
    other = next(t for t in link.tasks.values() if t.id not in board.entries)
    link.delivered.append(other.id)  # handed over, not on the deployment's board yet
    work = LinkWork(link, board)
    assert await work.next_round(PhaseResult("deploy")) == []  # a round: the tasks come as a task change
    assert work.took_nothing()  # the round is over and the board did not take it (refused)
    t0 = time.monotonic()
    assert await work.next_round(PhaseResult("deploy")) == []
    assert time.monotonic() - t0 >= STANDBY_POLL
    board.add(other)  # this time the round takes it in
    assert not work.took_nothing()
