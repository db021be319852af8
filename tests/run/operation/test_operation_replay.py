"""Resuming an operation, its parts on their own: the journal replayed into the operation's board
(:func:`replay_operation`), and the reconciliation's reading of a rover's current mission item
(:func:`reconcile_operation`) with vehicles standing in for what telemetry says after a restart."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as M

from fleetctl.mavlink.vehicle import MISSION_STATE_COMPLETE
from fleetctl.run.operation.board import SortieStatus
from fleetctl.run.operation.resume import reconcile_operation, replay_operation
from tests.run.ctl_helpers import mission_from
from tests.run.operation.ops_helpers import small_operation

T0 = 1_800_000_000.0  # unix s of the carrier's start
SCALE = 10.0


def rec(kind: str, t: float, **data: Any) -> dict[str, Any]:
    return {"kind": kind, "t": T0 + t / SCALE, **data}  # t: operation s


def story() -> list[dict[str, Any]]:
    """r1 launched for t2, t3 (t2 done, t3 started), r2 for t5 (started), r2's earlier sortie
    lost with t6 started, t4 retimed to 40 s, t7 added, t1 removed, a swap of r1."""
    return [
        rec("run", -5.0, command="run", speedup=SCALE), rec("phase", -1.0, phase="operation"),
        rec("carrier_started", 0.0, stops=6), rec("plan", 0.0, plan="operation", makespan=180.0),
        rec("launch", 1.0, vehicle="r2", task="t6", stop=1),
        rec("sortie_launched", 2.0, vehicle="r2", sortie=0, tasks=["t6"], stop=1, work=[["t6", 1, 3]]),
        rec("task_started", 6.0, vehicle="r2", task="t6", sortie=0),
        rec("sortie_lost", 9.0, vehicle="r2", sortie=0, tasks_left=["t6"]),
        rec("battery_swapped", 12.0, vehicle="r1", started=2.0, done=12.0),
        rec("tasks_changed", 13.0, add=["t7"], remove=["t1"], added=[
            {"id": "t7", "position": [30, -10, 4], "duration": 45.0, "work": "hover"}],
            retimed=[{"id": "t4", "position": [80, 20, 4], "duration": 40.0, "work": "hover"}]),
        rec("replan", 13.5, n=1, cause="tasks changed"),
        rec("launch", 14.0, vehicle="r1", task="t2", stop=2),
        rec("sortie_launched", 15.0, vehicle="r1", sortie=3, tasks=["t2", "t3"], stop=2,
            work=[["t2", 1, 2], ["t3", 3, 5]]),
        rec("task_started", 20.0, vehicle="r1", task="t2", sortie=3),
        rec("task_done", 50.0, vehicle="r1", task="t2", sortie=3, worked=30.0, duration=30.0),
        rec("task_started", 60.0, vehicle="r1", task="t3", sortie=3),
        rec("launch", 70.0, vehicle="r2", task="t5", stop=3),
    ]


def test_the_journal_is_replayed_into_the_operation_s_board(tmp_path: Path) -> None:
    rep = replay_operation(story(), mission_from(small_operation(), tmp_path), SCALE)
    b = rep.board
    assert sorted(rep.tasks) == ["t2", "t3", "t4", "t5", "t6", "t7"]
    assert rep.added == ["t7"] and rep.removed == ["t1"]
    assert rep.tasks["t4"].duration == 40.0 and b.tasks["t4"].duration == 40.0  # retimed
    assert rep.tasks["t7"].duration == 45.0 and rep.tasks["t7"].position == (30.0, -10.0, 4.0)
    assert b.tasks["t2"].done == 50.0 and b.tasks["t2"].rover == "r1"
    assert b.tasks["t3"].started == 60.0 and b.tasks["t3"].done is None and b.tasks["t3"].seen_start
    assert b.tasks["t6"].started is None and b.tasks["t6"].rover is None  # its rover lost: redone in full
    assert [(s.index, s.rover, s.status) for s in b.sorties] == [(0, "r2", SortieStatus.LOST),
                                                                 (3, "r1", SortieStatus.FLYING)]
    assert b.lost == ["r2"] and b.swaps == [("r1", 12.0)] and b.next_index == 4
    assert rep.work[3][1].task == "t3" and (rep.work[3][1].arrive_seq, rep.work[3][1].done_seq) == (3, 5)
    assert rep.launching == {"r2": 3}  # written ahead, never journalled flown
    assert rep.replans == 1 and rep.planned == 180.0 and rep.elapsed(T0 + 8.0) == 80.0


@dataclass
class Seen:
    """A vehicle as telemetry shows it after the controller restarted (what reconcile reads)."""

    name: str
    connected: bool = True
    lost: bool = False
    armed: bool = True
    deck: bool = False
    mission_current: int | None = None
    mission_state: int | None = None
    battery_pct: float | None = 60.0

    async def wait_until(self, predicate: Any, timeout: float, what: str) -> None:
        if not predicate(self):
            raise TimeoutError(what)


@dataclass
class Fleet:
    rovers: dict[str, Seen]


class Journal:
    def __init__(self) -> None:
        self.events: list[tuple[str, str | None, dict[str, Any]]] = []

    def event(self, kind: str, text: str, vehicle: str | None = None, **data: Any) -> None:
        self.events.append((kind, vehicle, data))


async def _reconcile(tmp_path: Path, r1: Seen, r2: Seen) -> tuple[Any, dict[str, Any], Journal, list[str]]:
    rep = replay_operation(story(), mission_from(small_operation(), tmp_path), SCALE)
    journal, disarmed = Journal(), []

    async def disarm(v: Any) -> None:
        disarmed.append(v.name)

    found = await reconcile_operation(rep, Fleet({"r1": r1, "r2": r2}), journal,  # type: ignore[arg-type]
                                      disarm, lambda v: v.deck, T0 + 9.0)
    return rep, found, journal, disarmed


async def test_a_task_whose_timing_item_passed_while_the_controller_was_down_is_done(tmp_path: Path) -> None:
    # r1's firmware is past t3's NAV_DELAY (item 5, the last one: mission complete); r2 armed on the deck
    rep, found, journal, disarmed = await _reconcile(
        tmp_path, Seen("r1", mission_current=5, mission_state=MISSION_STATE_COMPLETE), Seen("r2", deck=True))
    assert rep.board.tasks["t3"].done == 90.0 and found["done_while_down"] == ["t3"]
    assert [(v, d["worked"]) for k, v, d in journal.events if k == "task_done"] == [("r1", None)]
    assert found["in_air"] == {"r1": []} and "r1" in rep.in_air
    assert disarmed == ["r2"] and found["disarmed"] == ["r2"]


@pytest.mark.parametrize("state", [None, M.MISSION_STATE_ACTIVE])  # (ArduPilot and PX4 send ACTIVE)
async def test_a_task_whose_arrival_passed_is_being_worked_from_its_journalled_start(
        tmp_path: Path, state: int | None) -> None:
    # r1 at t3's NAV_DELAY (item 5 current, not complete); r2 in the air from a launch never journalled flown
    rep, found, journal, _ = await _reconcile(tmp_path, Seen("r1", mission_current=5, mission_state=state),
                                              Seen("r2"))
    t3 = rep.board.tasks["t3"]
    assert t3.done is None and t3.started == 60.0 and t3.seen_start  # the journal saw its start
    assert not [e for e in journal.events if e[0] in ("task_done", "task_started")]
    assert found["called_back"] == ["r2"] and rep.in_air["r2"].tasks == []  # its work is not counted
    assert [d["tasks"] for k, v, d in journal.events if k == "sortie_launched"] == [[]]


async def test_a_rover_that_does_not_answer_is_lost_with_its_work(tmp_path: Path) -> None:
    rep, found, journal, _ = await _reconcile(tmp_path, Seen("r1", connected=False), Seen("r2", deck=True,
                                                                                             armed=False))
    assert found["lost"] == ["r1"] and rep.board.tasks["t3"].started is None  # done again in full
    assert rep.board.tasks["t2"].done == 50.0  # work done stays done
    assert [d["tasks_left"] for k, v, d in journal.events if k == "sortie_lost"] == [["t3"]]
    assert not rep.in_air and not found["disarmed"]


async def test_a_rover_found_on_the_deck_is_back_and_its_tasks_not_done_go_back(tmp_path: Path) -> None:
    rep, found, journal, _ = await _reconcile(tmp_path, Seen("r1", deck=True), Seen("r2", deck=True,
                                                                                     armed=False))
    assert found["back_on_deck"] == ["r1"] and rep.board.sorties[1].status is SortieStatus.ABOARD
    assert rep.board.tasks["t3"].started is None and rep.board.tasks["t3"].rover is None
    assert [k for k, *_ in journal.events] == ["sortie_back"]
