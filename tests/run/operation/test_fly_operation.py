"""`fleetctl run` flies a long operation on the embedded simulated fleet: sorties launched,
tasks worked for their durations (timed by the firmware), rovers picked up, batteries swapped,
every rover back on the deck."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path

from fleetctl.run.flight import execute
from tests.run.ctl_helpers import mission_from
from tests.run.operation.ops_helpers import journal, small_operation


async def test_a_small_operation_flies_to_complete(tmp_path: Path) -> None:
    mission = mission_from(small_operation(), tmp_path)
    out = await asyncio.wait_for(execute(mission, "run", run_dir=tmp_path / "run", force=True), 120)
    s = out.summary
    assert out.exit_code == 0, s
    assert s["result"] == "complete"
    tasks = {t.id: mission.task_work(t.id).duration for t in mission.tasks}
    assert sorted(s["tasks_done"]) == sorted(tasks) == sorted(s["tasks_reached"])
    assert sorted(s["rovers_loaded"]) == ["r1", "r2"] and not s["rovers_lost"]
    records = journal(tmp_path / "run")
    done = [r for r in records if r["kind"] == "task_done"]
    assert sorted(r["task"] for r in done) == sorted(tasks)  # each task worked once
    for r in done:  # for its duration: the firmware timed it (a landed task counts its touch-down too)
        assert r["worked"] >= tasks[r["task"]] - 0.2, r
    launched = [r for r in records if r["kind"] == "sortie_launched"]
    back = [r for r in records if r["kind"] == "sortie_back"]
    assert len(launched) == len(back) > 2  # rovers fly again: more sorties than rovers
    plan = json.loads((tmp_path / "run" / "plan.json").read_text())
    swaps = [r for r in records if r["kind"] == "battery_swapped"]
    planned = [e for rows in plan["rovers"].values() for e in rows if e["kind"] == "swap"]
    assert len(swaps) == len(planned) >= 1  # every planned swap flown and journalled
    assert s["makespan_flown"] is not None and s["makespan_planned"] is not None
