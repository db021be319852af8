"""Two MAVLink links in one controller: each simulated carrier is a link of its own with its
deck's rovers, and both links use the same system ids (carriers 1, rovers 11 and 12). The run
flies, dwells and collects as if the ids were all different: every vehicle is addressed by its
link and system id, so no command, reply or telemetry reaches the namesake on the other link."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from fleetctl.journal import read_journal
from fleetctl.run.flight import execute
from tests.run.teams.teams_helpers import mission_from, two_teams

pytestmark = pytest.mark.slow

SPEEDUP = 20.0


def same_ids_on_two_links() -> dict[str, Any]:
    d = two_teams()
    for c in d["carriers"]:
        c["sysid"], c["fleet"] = 1, {"count": 2, "sysid_start": 11}
    return d


async def test_two_links_reusing_system_ids_fly_deploy_dwell_collect(tmp_path: Path) -> None:
    m = mission_from(same_ids_on_two_links(), tmp_path)
    sims: list[Any] = []
    out = await execute(m, "run", run_dir=tmp_path / "run", speedup=SPEEDUP, on_sim=sims.append)
    s = out.summary
    assert out.exit_code == 0 and s["result"] == "complete", s
    assert sorted(s["tasks_reached"]) == ["t1", "t2", "t3", "t4"] and s["tasks_unserved"] == []
    assert sorted(s["rovers_loaded"]) == ["r1", "r2", "r3", "r4"]
    records = read_journal(tmp_path / "run" / "journal.jsonl")
    assert not [r for r in records if r["kind"] == "route_conflict"]  # nobody heard as its namesake
    connected = {r["vehicle"]: (r["url"], r["sysid"]) for r in records if r["kind"] == "connected"}
    assert {vid: sysid for vid, (_url, sysid) in connected.items()} == {
        "c1": 1, "r1": 11, "r2": 12, "c2": 1, "r3": 11, "r4": 12}
    link1, link2 = connected["c1"][0], connected["c2"][0]
    assert link1 != link2 and sims[0].endpoints == {
        "c1": link1, "r1": link1, "r2": link1, "c2": link2, "r3": link2, "r4": link2}
    teams = json.loads((tmp_path / "run" / "plan.json").read_text())["teams"]
    for team in s["teams"]:  # each task reached by the rover its team planned for it, over its own link
        plan = next(t for t in teams if t["carrier"] == team["carrier"])
        planned = {leg["task"]: leg["rover"] for st in plan["stops"] for leg in st["rovers"]}
        journal = read_journal(Path(team["deploy"]["records"]) / "journal.jsonl")
        reached = {r["task"]: r["vehicle"] for r in journal if r["kind"] == "task_reached"}
        assert reached == planned and planned
    world = sims[0].world
    assert all(world.rovers[rid].loaded for rid in ("r1", "r2", "r3", "r4"))  # every rover back on a deck
    # each link has a MAVLink log of its own, so the replay tells the namesakes apart
    from fleetctl.views.replay import load_run

    logs = sorted(p.name for p in (tmp_path / "run").glob("*.tlog"))
    assert logs == ["traffic-c2.tlog", "traffic.tlog"], logs
    heard = {sample.vehicle for sample in load_run(tmp_path / "run").samples}
    assert heard == {"c1", "r1", "r2", "c2", "r3", "r4"}, heard
