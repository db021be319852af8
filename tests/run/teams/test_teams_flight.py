"""Two teams flown in one controller on the embedded simulated fleet:
every task reached once by the team it was shared to, each team's flown stops those of its plan,
the makespan the latest team's; a collection landing a rover on the other team's carrier; a
hand-over when a team's carrier is lost mid-deployment; one team flown alone."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Any

import pytest

from fleetctl.journal import read_journal
from fleetctl.run.flight import execute
from fleetctl.run.teams import fly_team
from sitl import Fault
from tests.run.teams.teams_helpers import mission_from, two_teams

pytestmark = pytest.mark.slow

SPEEDUP = 20.0


def _plan_stops(path: Path) -> list[dict[str, str]]:
    """Per stop of a plan: task -> the rover planned for it."""
    plan = json.loads(path.read_text())
    return [{leg["task"]: leg["rover"] for leg in s["rovers"]} for s in plan["stops"]]


def _flown_stops(run_dir: Path) -> list[dict[str, str]]:
    """Per stop the carrier reached: task -> the rover launched there for it."""
    stops: list[dict[str, str]] = []
    for r in read_journal(run_dir / "journal.jsonl"):
        if r["kind"] == "stop_reached":
            assert r["stop"] == len(stops) + 1
            stops.append({})
        elif r["kind"] == "rover_launched":
            assert r["stop"] == len(stops)
            stops[-1][r["task"]] = r["vehicle"]
    return stops


async def test_two_teams_deploy_in_one_controller(tmp_path: Path) -> None:
    m = mission_from(two_teams(), tmp_path)
    out = await execute(m, "deploy", run_dir=tmp_path / "run", speedup=SPEEDUP)
    s = out.summary
    assert out.exit_code == 0 and s["result"] == "complete", s
    assert sorted(s["tasks_reached"]) == ["t1", "t2", "t3", "t4"] and s["tasks_unserved"] == []
    teams = json.loads((tmp_path / "run" / "plan.json").read_text())["teams"]
    shared: dict[str, set[str]] = {
        t["carrier"]: {leg["task"] for st in t["stops"] for leg in st["rovers"]} for t in teams
    }
    assert set().union(*shared.values()) == {"t1", "t2", "t3", "t4"}
    assert sum(len(v) for v in shared.values()) == 4  # every task to exactly one team
    reached_by: list[str] = []
    for team in s["teams"]:
        cid, dep = team["carrier"], team["deploy"]
        assert set(dep["tasks_reached"]) == shared[cid] == set(dep["tasks_planned"])
        reached_by += dep["tasks_reached"]
        records = Path(dep["records"])
        own = json.loads((records / "summary.json").read_text())
        assert own["result"] == "complete" and set(own["tasks_reached"]) == shared[cid]
        planned = _plan_stops(records / "plan.json")
        assert _flown_stops(records) == planned and len(planned) > 0  # its stops, in order, as planned
        reached = [r for r in read_journal(records / "journal.jsonl") if r["kind"] == "task_reached"]
        assert sorted(r["task"] for r in reached) == sorted(shared[cid])  # once each
    assert sorted(reached_by) == ["t1", "t2", "t3", "t4"]
    spans = [t["deploy"]["makespan_planned"] for t in s["teams"]]
    assert s["makespan_planned"] == max(spans)  # the latest team's
    allocated = [t["deploy"]["makespan_allocated"] for t in s["teams"]]
    assert s["makespan_allocated"] == max(allocated) == round(max(t["makespan"] for t in teams), 3)
    flown = [t["deploy"]["makespan_flown"] for t in s["teams"]]
    assert s["makespan_flown"] == max(flown)  # the latest team's
    kinds = [r["kind"] for r in read_journal(tmp_path / "run" / "journal.jsonl")]
    assert "teams_plan" in kinds and kinds.count("team") == 4 and kinds[-1] == "summary"


async def test_two_teams_run_deploy_dwell_collect(tmp_path: Path) -> None:
    m = mission_from(two_teams(), tmp_path)
    out = await execute(m, "run", run_dir=tmp_path / "run", speedup=SPEEDUP)
    s = out.summary
    assert out.exit_code == 0 and s["result"] == "complete", s
    assert sorted(s["rovers_loaded"]) == ["r1", "r2", "r3", "r4"]
    ph = s["phases"]
    total = ph["deploy"]["flown"] + ph["dwell"]["flown"] + ph["collect"]["flown"]
    assert s["makespan_flown"] == round(total, 3)
    assert (tmp_path / "run" / "plan-collect.json").exists()


async def test_a_collection_lands_a_rover_on_the_other_teams_carrier(tmp_path: Path) -> None:
    d = two_teams(
        tasks=[],
        collection={
            "rovers": [
                {"id": "r1", "position": [82, 18, 5], "range": 40.0},
                {"id": "r3", "position": [76, 22, 4], "range": 40.0},
            ]
        },
    )
    m = mission_from(d, tmp_path)
    sims: list[Any] = []
    out = await execute(m, "collect", run_dir=tmp_path / "run", speedup=SPEEDUP, on_sim=sims.append)
    s = out.summary
    assert out.exit_code == 0 and s["result"] == "complete", s
    assert sorted(s["rovers_loaded"]) == ["r1", "r3"]
    c2 = next(t for t in s["teams"] if t["carrier"] == "c2")
    assert "r1" in c2["collect"]["rovers_loaded"]  # r1 is c1's rover
    world = sims[0].world
    assert world.rovers["r1"].loaded and world.rovers["r1"].carrier.id == "c2"
    assert sorted(world.loaded_rovers("c2")) == ["r1", "r3", "r4"]


async def test_a_lost_carrier_hands_its_tasks_to_the_other_team(tmp_path: Path) -> None:
    c = two_teams()["carriers"]
    c[1]["fleet"] = {"count": 4, "sysid_start": 31}  # c2 has rovers to spare
    tasks = [
        {"id": "t1", "position": [-10, 90, 5]},
        {"id": "t2", "position": [10, 100, 4]},
        {"id": "t3", "position": [75, 25, 5]},
        {"id": "t4", "position": [95, 20, 4]},
    ]
    m = mission_from(
        two_teams(carriers=c, tasks=tasks, links={"heartbeat_timeout": 2.0, "reassign_after": 1.0}), tmp_path
    )
    watchers: list[asyncio.Task[None]] = []

    def on_sim(sim: Any) -> None:
        async def fail_c1_when_it_drives() -> None:
            await sim.wait_for(lambda: sim.world.carriers["c1"].speed > 0.5, timeout=60.0)
            sim.inject(Fault("dropout", vehicle="c1", at=sim.sim_time))  # for good

        watchers.append(asyncio.create_task(fail_c1_when_it_drives()))

    out = await execute(m, "deploy", run_dir=tmp_path / "run", speedup=10.0, on_sim=on_sim)
    await asyncio.gather(*watchers)
    s = out.summary
    assert s["result"] == "complete", s
    assert sorted(s["tasks_reached"]) == ["t1", "t2", "t3", "t4"]
    c1 = next(t for t in s["teams"] if t["carrier"] == "c1")
    c2 = next(t for t in s["teams"] if t["carrier"] == "c2")
    assert set(c1["deploy"]["tasks_planned"]) == {"t1", "t2"} and c1["lost"]
    assert c1["deploy"]["tasks_reached"] == []
    assert set(c2["deploy"]["tasks_reached"]) == {"t1", "t2", "t3", "t4"}
    assert [(h["from"], h["to"], sorted(h["tasks"])) for h in s["handovers"]] == [("c1", "c2", ["t1", "t2"])]
    records = read_journal(tmp_path / "run" / "journal.jsonl")
    assert [r["to_team"] for r in records if r["kind"] == "handover"] == ["c2"]


async def test_one_team_flown_alone(tmp_path: Path) -> None:
    m = mission_from(two_teams(), tmp_path)
    out = await fly_team(m, "c2", "deploy", tasks=["t3", "t4"], run_dir=tmp_path / "c2", speedup=SPEEDUP)
    s = out.summary
    assert out.exit_code == 0 and sorted(s["tasks_reached"]) == ["t3", "t4"], s
    assert [
        r["vehicle"] for r in read_journal(tmp_path / "c2" / "journal.jsonl") if r["kind"] == "connected"
    ] == ["c2", "r3", "r4"]


async def test_a_team_out_of_rovers_hands_its_unserved_task_over(tmp_path: Path) -> None:
    c = two_teams()["carriers"]
    c[1]["fleet"] = {"count": 4, "sysid_start": 31}
    tasks = [
        {"id": "t1", "position": [-10, 20, 5]},
        {"id": "t2", "position": [10, 30, 4]},
        {"id": "t3", "position": [75, 70, 5]},
        {"id": "t4", "position": [95, 80, 4]},
    ]
    faults = [{"kind": "refuse_arm", "vehicle": "r1"}]  # c1 has no spare for it
    m = mission_from(two_teams(carriers=c, tasks=tasks, sim={"speedup": SPEEDUP, "faults": faults}), tmp_path)
    out = await execute(m, "deploy", run_dir=tmp_path / "run", speedup=SPEEDUP)
    s = out.summary
    assert s["result"] == "complete", s
    assert sorted(s["tasks_reached"]) == ["t1", "t2", "t3", "t4"]
    (h,) = s["handovers"]
    assert (h["from"], h["to"], len(h["tasks"])) == ("c1", "c2", 1) and "could not serve" in h["why"]
    c2 = next(t for t in s["teams"] if t["carrier"] == "c2")
    assert h["tasks"][0] in c2["deploy"]["tasks_reached"]
    records = read_journal(Path(c2["deploy"]["records"]) / "journal.jsonl")
    changes = [r["source"] for r in records if r["kind"] == "tasks_changed"]
    assert changes == ["team c1"] or c2["deploy"]["rounds"] == 2  # while deploying, or after
    c1 = next(t for t in s["teams"] if t["carrier"] == "c1")
    assert h["tasks"][0] not in c1["deploy"]["tasks_reached"] and len(c1["deploy"]["tasks_reached"]) == 1


async def test_an_interrupted_teams_run_holds_every_team(tmp_path: Path) -> None:
    m = mission_from(two_teams(), tmp_path)
    sims: list[Any] = []
    task = asyncio.create_task(
        execute(m, "deploy", run_dir=tmp_path / "run", speedup=SPEEDUP, on_sim=sims.append)
    )
    while not sims:
        await asyncio.sleep(0.05)
    sim = sims[0]
    await sim.wait_for(lambda: any(not r.on_ground for r in sim.world.rovers.values()), timeout=60.0)
    task.cancel()
    out = await asyncio.wait_for(task, 60.0)
    assert out.exit_code == 130 and out.summary["result"] == "interrupted"
    for cid in ("c1", "c2"):
        own = json.loads((tmp_path / "run" / "teams" / cid / "deploy" / "summary.json").read_text())
        assert own["result"] == "interrupted"
    kinds = [r["kind"] for r in read_journal(tmp_path / "run" / "journal.jsonl")]
    assert "interrupted" in kinds and kinds[-1] == "summary"
    holds = [
        r
        for cid in ("c1", "c2")
        for r in read_journal(tmp_path / "run" / "teams" / cid / "deploy" / "journal.jsonl")
        if r["kind"] == "hold"
    ]
    assert holds  # the airborne rovers were told to hold


def test_fleetctl_deploy_flies_two_teams_headless(tmp_path: Path, capsys: Any) -> None:
    from fleetctl.cli import main
    from tests.run.teams.teams_helpers import write_mission

    path = write_mission(two_teams(), tmp_path / "two.yaml")
    rc = main(["deploy", "--mission", str(path), "--headless", "--speedup", "20", "--runs", str(tmp_path)])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "deploy complete: 4/4 tasks reached" in out
    for cid in ("c1", "c2"):
        assert f"] {cid} task_reached" in out  # every event line names its team
        assert f"  team {cid}; deploy: 2/2 tasks reached in" in out


def test_team_views() -> None:
    import io

    from fleetctl.run.teams.views import SharedView, team_views
    from fleetctl.views.dashboard import HeadlessView, LiveView
    from fleetctl.views.view import Views

    heads = team_views(HeadlessView(io.StringIO()), ["c1", "c22"])
    assert [v.prefix for v in heads.values()] == ["c1  ", "c22 "]  # type: ignore[union-attr]
    live = team_views(LiveView(), ["c1", "c2"])
    assert [(type(v), v.team) for v in live.values()] == [(SharedView, "c1"), (SharedView, "c2")]  # type: ignore[union-attr]
    both = team_views(Views(HeadlessView(io.StringIO()), LiveView()), ["c1", "c2"])
    assert all(isinstance(v, Views) for v in both.values())
    assert team_views(None, ["c1"]) == {"c1": None}


async def test_a_team_lost_with_a_rover_in_flight_is_stopped_and_its_tasks_served(tmp_path: Path) -> None:
    c = two_teams()["carriers"]
    c[1]["position"] = [300, 0]  # far: c1's two stops are c1's
    c[1]["fleet"] = {"count": 4, "sysid_start": 31}
    tasks = [
        {"id": "t1", "position": [-10, 20, 5]},
        {"id": "t2", "position": [-20, 110, 4]},
        {"id": "t3", "position": [300, 25, 5]},
        {"id": "t4", "position": [320, 20, 4]},
    ]
    links = {"heartbeat_timeout": 2.0, "reassign_after": 1.0}
    m = mission_from(two_teams(carriers=c, tasks=tasks, links=links), tmp_path)
    watchers: list[asyncio.Task[None]] = []

    def on_sim(sim: Any) -> None:
        async def fail_c1_once_a_rover_flies() -> None:
            c1_rovers = [sim.world.rovers[r] for r in ("r1", "r2")]
            await sim.wait_for(lambda: any(not r.on_ground for r in c1_rovers), timeout=60.0)
            sim.inject(Fault("dropout", vehicle="c1", at=sim.sim_time))

        watchers.append(asyncio.create_task(fail_c1_once_a_rover_flies()))

    out = await execute(m, "deploy", run_dir=tmp_path / "run", speedup=10.0, on_sim=on_sim)
    await asyncio.gather(*watchers)
    s = out.summary
    c1 = next(t for t in s["teams"] if t["carrier"] == "c1")
    assert sorted(c1["deploy"]["tasks_planned"]) == ["t1", "t2"] and c1["lost"], s
    assert c1["deploy"]["result"] == "interrupted"  # stopped once c2 was done: its rover in the air holds
    assert sorted(s["tasks_reached"]) == ["t1", "t2", "t3", "t4"] and s["result"] == "complete", s
    handed = sorted(t for h in s["handovers"] if (h["from"], h["to"]) == ("c1", "c2") for t in h["tasks"])
    assert handed == ["t1", "t2"] and c1["deploy"]["tasks_reached"] == []
    kinds = [(r["kind"], r.get("status")) for r in read_journal(tmp_path / "run" / "journal.jsonl")]
    assert ("team", "stopped") in kinds


async def test_the_web_map_shows_a_two_team_run(tmp_path: Path) -> None:
    import io

    import aiohttp

    from fleetctl.views.dashboard import HeadlessView
    from fleetctl.views.view import Views
    from fleetctl.views.web import WebMapView

    m = mission_from(two_teams(), tmp_path)
    web = WebMapView("127.0.0.1", 0, origin=m.origin)
    out_lines = io.StringIO()
    docs: list[dict[str, Any]] = []

    async def look() -> None:
        await asyncio.wait_for(web.ready.wait(), 60.0)
        async with aiohttp.ClientSession() as session:
            for _ in range(200):
                async with session.get(web.server.url + "state") as resp:
                    docs.append(await resp.json())
                teams = docs[-1].get("plan", {}).get("teams", [])
                if [t["team"] for t in teams if t["kind"] == "deploy"] == ["c1", "c2"]:
                    return
                await asyncio.sleep(0.05)

    looker = asyncio.create_task(look())
    view = Views(HeadlessView(out_lines), web)
    out = await execute(m, "deploy", run_dir=tmp_path / "run", speedup=SPEEDUP, view=view)
    await asyncio.wait_for(looker, 10.0)
    assert out.exit_code == 0 and web.error is None
    layers = docs[-1]["plan"]["teams"]  # every team's plan on the map, each in its colour
    assert [(x["team"], x["kind"]) for x in layers] == [("c1", "deploy"), ("c2", "deploy")]
    assert all(len(x["route"]) > 1 for x in layers) and layers[0]["colour"] != layers[1]["colour"]
    assert {v["team"] for v in docs[-1]["frame"]["vehicles"] if v["role"] == "carrier"} == {"c1", "c2"}
    assert "c1 task_reached" in out_lines.getvalue() and "c2 task_reached" in out_lines.getvalue()


def test_collect_team_collects_the_rovers_of_its_own_deck(tmp_path: Path) -> None:
    """``fleetctl collect --team c2`` on missions/two_carriers.yaml: carrier c2 alone collects r9..r16
    (the collection section's rovers of its deck), one team's records."""
    import yaml

    from fleetctl.cli import main

    two = yaml.safe_load((Path(__file__).parents[3] / "missions" / "two_carriers.yaml").read_text())
    path = tmp_path / "two.yaml"
    path.write_text(yaml.safe_dump(two))
    summary = tmp_path / "summary.json"
    rc = main(["collect", "--mission", str(path), "--team", "c2", "--headless", "--yes", "--speedup", "20",
               "--run-dir", str(tmp_path / "run"), "--summary", str(summary)])
    s = json.loads(summary.read_text())
    assert rc == 0, s
    c2 = {r["id"] for r in two["collection"]["rovers"]} & {f"r{i}" for i in range(9, 17)}
    # each of c2's rovers loaded, or left out because its range cannot reach c2 alone (c1 is not there
    # to help: the file's ranges are tight)
    assert s["rovers_loaded"] and set(s["rovers_loaded"]) | set(s["rovers_unreachable"]) == c2, s
    journal = read_journal(tmp_path / "run" / "journal.jsonl")
    connected = {r["vehicle"] for r in journal if r["kind"] == "connected"}
    assert "c2" in connected and connected <= {"c2", *(f"r{i}" for i in range(9, 17))}, connected


async def test_the_rovers_are_watched_during_the_dwell_of_several_teams(tmp_path: Path) -> None:
    """A rover's link drops while every team dwells: its loss and its return are told (journalled
    with the one-team wording) before the collection starts, and it is collected."""
    rovers = {**two_teams()["rovers"], "endurance_range": 3000.0}  # hovering 120 s leaves plenty
    m = mission_from(two_teams(dwell=120.0, rovers=rovers, links={"heartbeat_timeout": 2.0}), tmp_path)
    run_dir = tmp_path / "run"
    watchers: list[asyncio.Task[None]] = []

    def on_sim(sim: Any) -> None:
        async def drop_r3_while_dwelling() -> None:
            journal = run_dir / "journal.jsonl"
            await sim.wait_for(lambda: journal.exists() and '"kind":"dwell"' in journal.read_text(),
                               timeout=120.0)
            now = sim.sim_time
            sim.inject(Fault("dropout", vehicle="r3", at=now, until=now + 70.0))  # 3.5 wall s

        watchers.append(asyncio.create_task(drop_r3_while_dwelling()))

    out = await execute(m, "run", run_dir=run_dir, speedup=SPEEDUP, on_sim=on_sim)
    await asyncio.gather(*watchers)
    kinds = [(r["kind"], r.get("vehicle")) for r in read_journal(run_dir / "journal.jsonl")]
    dwell = kinds.index(("dwell", None))
    collect = next(i for i, k in enumerate(kinds) if k[0] == "teams_plan" and i > dwell)
    assert ("link_lost", "r3") in kinds[dwell:collect] and ("link_back", "r3") in kinds[dwell:collect], kinds
    assert out.summary["result"] == "complete" and "r3" in out.summary["rovers_loaded"], out.summary
