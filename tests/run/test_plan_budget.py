"""The controller budgets for itself: a rover in the air burns its battery while the
controller plans and checks its collection, so the plan and its energy check use the battery it
will have when the round flies (mission time since the reading, the planning still to come), and
each attempt's cost is journalled (``plan_budget``). End to end on the simulated fleet, with the
planner made slow in mission time; the same mission takes the same decisions at speed-up 1 and 20."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Any

import pytest

from fleetctl.run.flight import execute
from fleetctl.run.planning import Planning
from tests.run.ctl_helpers import mission_dict, mission_from
from tests.run.test_timed_collection import Recorder

SLOW = 6.0  # mission s each collection plan takes
# in the air: r1 near the start with little battery above its reserve, r2 further with plenty
ROVERS = [{"id": "r1", "position": [15, 5, 4], "range": 60.0},
          {"id": "r2", "position": [40, 20, 4], "range": 400.0}]


def slow_planner(monkeypatch: pytest.MonkeyPatch) -> None:
    plan = Planning.plan

    async def slow(self: Planning, kind: str, problem: Any):  # type: ignore[no-untyped-def]
        if kind == "collect":
            await self.ctx.sleep_mission(SLOW)
        return await plan(self, kind, problem)

    monkeypatch.setattr(Planning, "plan", slow)


Flown = tuple[dict[str, Any], list[dict[str, Any]], Recorder, float]


async def collect(tmp_path: Path, speedup: float, r1_range: float = 60.0) -> Flown:
    d = mission_dict(rovers=2, speedup=speedup)
    d["rovers"]["endurance_range"] = 1000.0
    d["collection"] = {"rovers": [ROVERS[0] | {"range": r1_range}, ROVERS[1]]}
    tmp_path.mkdir()
    mission = mission_from(d, tmp_path)
    rec = Recorder()
    try:
        out = await asyncio.wait_for(
            execute(mission, "collect", runs_dir=tmp_path / "runs", on_sim=rec.attach), 300)
    finally:
        if rec.task is not None:
            rec.task.cancel()
    records = [json.loads(line) for line in (out.run_dir / "journal.jsonl").read_text().splitlines()]
    return out.summary, records, rec, mission.rovers.reserve


def decisions(summary: dict[str, Any], records: list[dict[str, Any]]) -> tuple[Any, ...]:
    budget = [(r["attempt"], tuple(r["short"])) for r in records if r["kind"] == "plan_budget"]
    # (not rovers_loaded: a carrier stopping off its planned stop makes the re-targeted landing time
    # out at this branch's base, as in test_timed_collection's reserve test - not this item)
    return sorted(summary["rovers_unreachable"]), budget


async def test_slow_planning_is_paid_from_the_battery_and_budgeted(tmp_path: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    slow_planner(monkeypatch)
    summary, records, rec, reserve = await collect(tmp_path / "s20", 20.0)
    budget = [r for r in records if r["kind"] == "plan_budget"]
    assert budget, "every plan-and-check attempt is journalled"
    assert all(r["cost"] >= SLOW - 0.05 for r in budget), budget  # measured in mission time
    assert budget[0]["speedup"] == 20.0
    for rid in ("r1", "r2"):  # at touch-down (loaded, or landed where it is) above the reserve
        assert rec.lowest[rid] >= reserve - 1e-3, (rid, rec.lowest[rid], summary)
    # (r2 is loaded unless the carrier stops off its planned stop: the re-targeted landing then
    # times out, as in test_timed_collection's reserve test at this branch's base - not this item)
    # r1 has 12 s above its reserve: the planning ate most of it, so it is not collected but lands
    assert summary["rovers_unreachable"] == ["r1"], summary
    assert any(r["short"] == ["r1"] for r in budget), budget


@pytest.mark.slow
async def test_the_same_decisions_at_speedup_1_and_20(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    slow_planner(monkeypatch)
    fast = await collect(tmp_path / "s20", 20.0, r1_range=100.0)
    slow = await collect(tmp_path / "s1", 1.0, r1_range=100.0)
    assert decisions(*fast[:2]) == decisions(*slow[:2]) == ([], [(0, ())])
    for _, _, rec, reserve in (fast, slow):
        assert min(rec.lowest.values()) >= reserve - 1e-3, rec.lowest
