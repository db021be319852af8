"""Supervision events that test_replan.py does not cover, through the simulated fleet over
real UDP: a rover's battery drained to the reserve (``battery_low``), a rover pushed off its path
(``off_course``), the carrier lost while an airborne rover is at the reserve (it lands instead of
holding), and task changes handed to :meth:`Executor.submit_task_change` directly (as the MQTT bus
does): added / removed tasks and an invalid change that is rejected with the plan kept.

How the faults are made real:
* battery: a ``battery_drain`` fault with a large factor on the first rover launched; the sim only
  drains a battery while it flies. The test watches the simulated battery and clears the fault as
  soon as it is at the reserve, so the rover stays at the reserve instead of running empty.
* off course: the simulated rover's body is displaced sideways mid-climb through the sim's Python
  API (``sim.rover(id)._pos``: a gust pushing the airframe away); the autopilot then flies it back
  to its mission and the task is still reached.
"""

from __future__ import annotations

import asyncio
import contextlib
import copy
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from fleetctl.journal import Journal
from fleetctl.mavlink.fleet import connect_fleet
from fleetctl.mission import load_mission
from fleetctl.run.executor import Executor
from fleetctl.run.flight import execute
from fleetctl.run.sim import sim_mission_dict
from fleetctl.run.state import Event, FleetState
from planners.core.problem import Task
from sitl import Fault, FleetConfig, SimFleet
from tests.run.ctl_helpers import ORIGIN
from tests.run.test_replan import Trigger, assert_accounted, journal

SPEEDUP = 20.0
RESERVE = 0.1
TASKS = [{"id": "t1", "position": [22, 12, 3]}, {"id": "t2", "position": [-20, 15, 4]}]
TASK_IDS = ["t1", "t2"]
ROVERS3 = ["r1", "r2", "r3"]


def mission_dict(rovers: int = 3, carrier_speed: float = 8.0, rover_speed: float = 3.0,
                 speedup: float = SPEEDUP, far: bool = False) -> dict[str, Any]:
    """``far``: a third task 200 m up the road, so that the deployment outlasts a 1 Hz battery report."""
    return {
        "name": "supervision", "origin": ORIGIN,
        "carrier": {"id": "carrier", "connection": "sim", "sysid": 1, "position": [0, 0], "heading_deg": 0,
                    "max_speed": carrier_speed, "accel": None, "turn_rate": None, "unload_time": 1.0,
                    "load_time": 1.0},
        "rovers": {"max_speed": rover_speed, "accel": None, "deploy_range": 40.0, "endurance_range": 1800.0,
                   "reserve": RESERVE, "fleet": {"count": rovers, "sysid_start": 11}},
        "tasks": copy.deepcopy(TASKS) + ([{"id": "t3", "position": [0, 200, 3]}] if far else []),
        "sim": {"speedup": speedup, "faults": []},
        "links": {"heartbeat_timeout": 1.5},
    }


async def fly(tmp_path: Path, d: dict[str, Any],
              action: Callable[[Event, SimFleet, FleetState], None]) -> tuple[dict[str, Any], Trigger]:
    path = tmp_path / "mission.yaml"
    path.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
    mission = load_mission(path)
    cfg = FleetConfig.from_mission_dict(sim_mission_dict(mission))
    async with SimFleet(cfg) as sim:
        trig = Trigger(sim, action)
        run = execute(mission, "deploy", sim=sim, runs_dir=tmp_path / "runs", view=trig)
        out = await asyncio.wait_for(run, 90)
        assert sim.errors == 0, sim.last_error
    return out.summary | {"_exit": out.exit_code, "_dir": str(out.run_dir)}, trig


async def drain_to_reserve(sim: SimFleet, rid: str, factor: float = 150.0) -> None:
    """Drain ``rid``'s battery ``factor`` times faster while it flies, until it is at the reserve.

    The fault ends (``until``) when, flying at full speed (accel None), the battery is at 60 % of the
    reserve - below it, yet 18 m of normal flight from empty - so a starved poll cannot run it empty;
    the test clears it earlier when it sees the reserve."""
    body = sim.rover(rid)
    speed = body.spec.max_speed
    endurance = body.spec.endurance_range or 1.0
    flight = (body.battery - 0.6 * RESERVE) * endurance / factor  # metres at the drained rate
    sim.inject(Fault("battery_drain", vehicle=rid, factor=factor, at=sim.sim_time,
                     until=sim.sim_time + flight / speed))
    try:
        async with asyncio.timeout(20.0):
            while body.battery > RESERVE:
                await asyncio.sleep(0.002)
    finally:
        sim.clear_faults("battery_drain", vehicle=rid)
    assert body.battery > 0.0


def drain_first_launched(then: Callable[[str, SimFleet], None] = lambda rid, sim: None
                         ) -> tuple[Callable[[Event, SimFleet, FleetState], None], list[str], list[Any]]:
    victim: list[str] = []
    bg: list[Any] = []

    def action(ev: Event, sim: SimFleet, state: FleetState) -> None:
        if ev.kind == "rover_launched" and not victim:
            rid = ev.vehicle or ""
            victim.append(rid)

            async def go() -> None:
                await drain_to_reserve(sim, rid)
                then(rid, sim)
            bg.append(asyncio.get_running_loop().create_task(go()))
    return action, victim, bg


def records(s: dict[str, Any], kind: str) -> list[dict[str, Any]]:
    return [r for r in journal(s) if kind in (r.get("kind"), r.get("type"), r.get("event"))]


@pytest.mark.slow
async def test_battery_drained_to_the_reserve_is_a_battery_low_event(tmp_path: Path) -> None:
    action, victim, bg = drain_first_launched()
    s, trig = await fly(tmp_path, mission_dict(rovers=4, speedup=10.0, far=True), action)
    await asyncio.gather(*bg)  # the drain reached the reserve (else: TimeoutError)
    low = [e for e in trig.events if e.kind == "battery_low"]
    assert [e.vehicle for e in low] == victim, low  # that rover, once; no other rover
    assert low[0].data["battery_pct"] <= RESERVE * 100 and low[0].data["reserve"] == RESERVE
    rec = records(s, "battery_low")
    assert rec and victim[0] in json.dumps(rec[0]), rec
    assert s["_exit"] == 0 and s["tasks_reached"] == TASK_IDS + ["t3"], s  # at the reserve, it flies on
    assert_accounted(s, TASK_IDS + ["t3"], ROVERS3 + ["r4"])


async def test_rover_pushed_off_its_path_is_an_off_course_event(tmp_path: Path) -> None:
    pushed: list[str] = []

    def push(rid: str, sim: SimFleet) -> None:
        body = sim.rover(rid)
        body._pos[0] += 80.0  # 80 m east of its climb: far beyond OFF_COURSE_M
        body.moves += 1

    def action(ev: Event, sim: SimFleet, state: FleetState) -> None:
        if ev.kind == "rover_launched" and not pushed:
            pushed.append(ev.vehicle or "")
            asyncio.get_running_loop().call_later(0.05, push, ev.vehicle, sim)

    s, trig = await fly(tmp_path, mission_dict(), action)
    off = [e for e in trig.events if e.kind == "off_course"]
    assert [e.vehicle for e in off] == pushed, off  # once, for that rover only
    assert off[0].data["distance"] > 6.0
    assert records(s, "off_course")
    assert s["_exit"] == 0 and s["tasks_reached"] == TASK_IDS, s  # it flew back and reached its task
    assert_accounted(s, TASK_IDS, ROVERS3)


@pytest.mark.slow
async def test_carrier_lost_with_a_rover_at_the_reserve_lands_it(tmp_path: Path) -> None:
    def drop_carrier(rid: str, sim: SimFleet) -> None:
        sim.dropout("carrier", 3.0 * sim.speedup)  # 3 wall s

    action, victim, bg = drain_first_launched(drop_carrier)
    # slow rovers launched from the start: still flying when the carrier's loss is detected
    s, trig = await fly(tmp_path, mission_dict(carrier_speed=0.5, rover_speed=1.0, speedup=5.0), action)
    await asyncio.gather(*bg)
    rid = victim[0]
    kinds = [e.kind for e in trig.events]
    assert "carrier_lost" in kinds and "carrier_back" in kinds
    assert any(e.kind == "rover_landing" and e.vehicle == rid for e in trig.events), kinds
    cmds = [r.get("command") for r in records(s, "command") if r.get("vehicle") == rid]
    assert "land" in cmds and "pause" not in cmds, cmds  # landed, not held
    others = {r.get("vehicle") for r in records(s, "command") if r.get("command") == "pause"}
    assert rid not in others
    # the landed rover's task went back to the pool and a spare flew it once the carrier was back
    returned = [e for e in trig.events if e.kind == "task_returned" and e.vehicle == rid]
    assert returned, kinds
    task = returned[0].data["task"]
    assert task in s["tasks_reached"] and s["assignment"][task] != rid, s
    assert s["replans"] >= 1
    assert_accounted(s, TASK_IDS, ROVERS3)


async def test_submit_task_change_directly_adds_removes_and_rejects(tmp_path: Path) -> None:
    d = mission_dict(rovers=4)
    d["tasks"].append({"id": "t3", "position": [5, 60, 3]})  # far: removed before a rover flies to it
    path = tmp_path / "mission.yaml"
    path.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
    mission = load_mission(path)
    cfg = FleetConfig.from_mission_dict(sim_mission_dict(mission), speedup=SPEEDUP)
    events: list[Event] = []
    async with SimFleet(cfg) as sim, await connect_fleet(mission, sim.endpoints, timeout=5.0) as fleet:
        (tmp_path / "run").mkdir()
        jr = Journal(tmp_path / "run")
        state = FleetState(mission)
        state.add_listener(jr.on_event)
        state.add_listener(events.append)
        jr.start()
        ex = Executor(mission, fleet, state, record=jr.write, speedup=SPEEDUP, clock=lambda: sim.sim_time)
        submitted: list[str] = []

        def on_event(ev: Event) -> None:
            if ev.kind == "carrier_started" and not submitted:
                submitted.append("bad")
                ex.submit_task_change([Task("t1", (1.0, 1.0, 2.0))], [], "test: duplicate")
                ex.submit_task_change([], ["t42"], "test: unknown")
                ex.submit_task_change([Task("t8", (0.0, 20.0, 400.0))], [], "test: too high")
            elif ev.kind == "task_change_rejected" and len(submitted) == 1 and \
                    sum(e.kind == "task_change_rejected" for e in events) == 3:
                submitted.append("good")
                ex.submit_task_change([Task("t9", (-10.0, 30.0, 3.0))], ["t3"], "test: direct")
        state.add_listener(on_event)
        refresh = asyncio.create_task(_refresh(state, fleet))
        try:
            res = await asyncio.wait_for(ex.deploy(), 60)
        finally:
            refresh.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await refresh
            await ex.close()
            await jr.aclose()
    rejected = [e for e in events if e.kind == "task_change_rejected"]
    assert len(rejected) == 3, [e.text for e in rejected]
    assert "already exist" in rejected[0].text and "t42" in rejected[1].text
    assert "out of reach" in rejected[2].text
    assert submitted == ["bad", "good"]
    changed = [e for e in events if e.kind == "tasks_changed"]
    assert len(changed) == 1 and changed[0].data["source"] == "test: direct"
    assert res.complete, res.unserved_reasons
    assert res.tasks_added == ["t9"] and res.tasks_removed == ["t3"]
    assert sorted(res.tasks_reached) == ["t1", "t2", "t9"] and "t3" not in res.assignment
    assert "t3" not in res.tasks_unserved  # removed, not unserved
    rec = [json.loads(x) for x in (tmp_path / "run" / "journal.jsonl").read_text().splitlines()]
    assert any(r["kind"] == "replan" for r in rec)


async def _refresh(state: FleetState, fleet: Any) -> None:
    while True:
        state.refresh(fleet)
        await asyncio.sleep(0.1)
