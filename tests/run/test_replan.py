"""Supervision and replanning through the simulated fleet's faults over real UDP: rovers
lost on the deck / climbing / en route / on task / flying to a meeting point, no spare left, the
carrier lost, tasks added and removed by editing the running mission file, an invalid edit, and a
whole run under packet loss and latency. After each run the summary must account for every task
(reached, unserved with a reason, or removed) and every rover (loaded, lost, on the deck, or left
in the field with its last known position)."""

from __future__ import annotations

import asyncio
import copy
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from fleetctl.mavlink.fleet import Fleet
from fleetctl.mission import load_mission
from fleetctl.run.flight import execute
from fleetctl.run.sim import sim_mission_dict
from fleetctl.run.state import Event, FleetState
from fleetctl.views.view import View
from sitl import FleetConfig, SimFleet
from tests.run.ctl_helpers import ORIGIN

pytestmark = pytest.mark.slow

SPEEDUP = 8.0
TASKS = [{"id": "t1", "position": [15, 30, 3]}, {"id": "t2", "position": [-15, 35, 4]},
         {"id": "t3", "position": [30, 70, 3]}, {"id": "t4", "position": [-10, 90, 5]},
         {"id": "t5", "position": [25, 110, 4]}]


def mission_dict(rovers: int = 7, faults: list[dict[str, Any]] | None = None,
                 reassign_after: float = 2.0) -> dict[str, Any]:
    return {
        "name": "replantest", "origin": ORIGIN,
        "carrier": {"id": "carrier", "connection": "sim", "sysid": 1, "position": [0, 0], "heading_deg": 0,
                    "max_speed": 8.0, "accel": 4.0, "turn_rate": None, "unload_time": 1.0, "load_time": 1.0},
        "rovers": {"max_speed": 2.5, "accel": None, "deploy_range": 40.0, "endurance_range": 1800.0,
                   "reserve": 0.1, "fleet": {"count": rovers, "sysid_start": 11}},
        "tasks": copy.deepcopy(TASKS),
        "sim": {"speedup": SPEEDUP, "faults": faults or []},
        "links": {"heartbeat_timeout": 1.5, "reassign_after": reassign_after},
    }


class Trigger(View):
    """Calls ``action(event, sim, state)`` for every event of the run (to inject faults / edit files)."""

    def __init__(self, sim: SimFleet, action: Callable[[Event, SimFleet, FleetState], None]) -> None:
        self.sim, self.action, self.state = sim, action, None
        self.events: list[Event] = []

    def start(self, state: FleetState, fleet: Fleet | None) -> None:
        if self.state is None:
            self.state = state
            state.add_listener(self._on)

    def _on(self, ev: Event) -> None:
        self.events.append(ev)
        assert self.state is not None
        self.action(ev, self.sim, self.state)

    async def stop(self) -> None:
        pass


async def fly(tmp_path: Path, d: dict[str, Any], command: str,
              action: Callable[[Event, SimFleet, FleetState], None] = lambda *a: None,
              autopilot: str | None = None, **kw: Any) -> tuple[dict[str, Any], Trigger, SimFleet, Path]:
    """Fly ``command`` of mission ``d`` on the simulated fleet (its PX4 flavour, or ``autopilot``)."""
    path = tmp_path / "mission.yaml"
    path.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
    mission = load_mission(path)
    cfg = FleetConfig.from_mission_dict(sim_mission_dict(mission), speedup=SPEEDUP, autopilot=autopilot)
    async with SimFleet(cfg) as sim:
        trig = Trigger(sim, action)
        out = await asyncio.wait_for(execute(mission, command, sim=sim, runs_dir=tmp_path / "runs", view=trig,
                                             **kw), 150)
    return out.summary | {"_exit": out.exit_code, "_dir": str(out.run_dir)}, trig, sim, path


def assert_accounted(s: dict[str, Any], tasks: list[str], rovers: list[str]) -> None:
    removed = s.get("tasks_removed", [])
    assert sorted(s["tasks_reached"] + s["tasks_unserved"] + removed) == sorted(tasks), s
    assert not set(s["tasks_reached"]) & set(s["tasks_unserved"])
    assert set(s["tasks_unserved_reasons"]) == set(s["tasks_unserved"])
    assert all(s["tasks_unserved_reasons"].values())
    seen = s["rovers_loaded"] + s["rovers_lost"] + s["rovers_on_deck"] + list(s["rovers_left"])
    assert sorted(seen) == sorted(rovers), s
    for r in s["rovers_left"].values():
        assert r["position"] is not None
    for rid in s["rovers_lost"]:
        assert rid in s["rovers_lost_last_position"]


def journal(s: dict[str, Any]) -> list[dict[str, Any]]:
    return [json.loads(x) for x in (Path(s["_dir"]) / "journal.jsonl").read_text().splitlines()]


ROVERS7 = [f"r{i}" for i in range(1, 8)]
TASK_IDS = [t["id"] for t in TASKS]


def once(kind: str, then: Callable[[Event, SimFleet, FleetState], None]) -> Callable[..., None]:
    done: list[bool] = []

    def action(ev: Event, sim: SimFleet, state: FleetState) -> None:
        if ev.kind == kind and not done:
            done.append(True)
            then(ev, sim, state)
    return action


async def test_rover_lost_on_the_deck_is_replaced_by_a_spare(tmp_path: Path) -> None:
    def drop(ev: Event, sim: SimFleet, state: FleetState) -> None:
        sim.dropout("r3")

    s, trig, sim, _ = await fly(tmp_path, mission_dict(), "deploy", once("carrier_started", drop))
    assert s["_exit"] == 0, s
    assert s["tasks_reached"] == TASK_IDS and "r3" not in s["assignment"].values()
    assert "r3" in s["rovers_lost"]
    assert_accounted(s, TASK_IDS, ROVERS7)


@pytest.mark.parametrize("phase", ["climbing", "en_route", "on_task"])
async def test_rover_lost_in_flight_task_goes_to_a_spare(tmp_path: Path, phase: str) -> None:
    victim: list[str] = []

    def action(ev: Event, sim: SimFleet, state: FleetState) -> None:
        if victim:
            return
        if phase == "climbing" and ev.kind == "rover_launched":
            victim.append(ev.vehicle or "")
            sim.dropout(ev.vehicle or "")
        elif phase == "en_route" and ev.kind == "rover_launched":  # (the first stop's flights are long)
            victim.append(ev.vehicle or "")
            asyncio.get_running_loop().call_later(0.4, sim.dropout, ev.vehicle)
        elif phase == "on_task" and ev.kind == "task_reached":
            victim.append(ev.vehicle or "")
            sim.dropout(ev.vehicle or "")

    # hovering on task: a run, so that the loss is seen during the dwell and the collection
    command, kw = ("run", {"dwell": 3.0 * SPEEDUP}) if phase == "on_task" else ("deploy", {})
    s, trig, sim, _ = await fly(tmp_path, mission_dict(), command, action, **kw)
    assert victim
    assert s["tasks_reached"] == TASK_IDS
    assert victim[0] in s["rovers_lost"]
    if phase == "on_task":  # a task already reached stays reached; the others are collected
        assert victim[0] not in s["rovers_loaded"]  # reported lost, with its last position
        assert sorted(s["rovers_loaded"] + [victim[0]]) == sorted(s["assignment"].values())
    else:
        assert s["_exit"] == 0, s
        assert s["replans"] >= 1 and victim[0] not in s["assignment"].values()
        rec = [r for r in journal(s) if r.get("kind") == "replan" or r.get("type") == "replan"]
        assert rec and "lost in flight" in json.dumps(rec[0])
    assert_accounted(s, TASK_IDS, ROVERS7)


async def test_no_spare_left_the_task_is_unserved_with_its_reason(tmp_path: Path) -> None:
    def drop(ev: Event, sim: SimFleet, state: FleetState) -> None:
        sim.dropout(ev.vehicle or "")

    s, trig, sim, _ = await fly(tmp_path, mission_dict(rovers=5), "deploy", once("rover_launched", drop))
    assert s["_exit"] == 1 and s["result"] == "incomplete"
    assert len(s["tasks_unserved"]) == 1
    assert "no" in s["tasks_unserved_reasons"][s["tasks_unserved"][0]]
    assert_accounted(s, TASK_IDS, ROVERS7[:5])


async def test_carrier_lost_rovers_hold_and_resume(tmp_path: Path) -> None:
    def drop(ev: Event, sim: SimFleet, state: FleetState) -> None:
        sim.dropout("carrier", 3.0 * SPEEDUP)

    s, trig, sim, _ = await fly(tmp_path, mission_dict(), "deploy", once("rover_launched", drop))
    kinds = [e.kind for e in trig.events]
    assert "carrier_lost" in kinds and "carrier_back" in kinds
    assert s["_exit"] == 0, s
    assert s["tasks_reached"] == TASK_IDS
    assert_accounted(s, TASK_IDS, ROVERS7)


async def test_tasks_added_and_removed_by_editing_the_mission_file(tmp_path: Path) -> None:
    def edit(ev: Event, sim: SimFleet, state: FleetState) -> None:
        d = mission_dict()
        d["tasks"] = [t for t in d["tasks"] if t["id"] != "t4"] + [{"id": "t9", "position": [-20, 60, 3]}]
        (tmp_path / "mission.yaml").write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")

    s, trig, sim, _ = await fly(tmp_path, mission_dict(), "deploy", once("stop_reached", edit))
    assert s["_exit"] == 0, s
    assert s["tasks_added"] == ["t9"] and s["tasks_removed"] == ["t4"]
    assert sorted(s["tasks_reached"]) == sorted(["t1", "t2", "t3", "t5", "t9"])
    assert s["replans"] >= 1
    assert_accounted(s, TASK_IDS + ["t9"], ROVERS7)


async def test_invalid_edit_is_rejected_and_the_plan_kept(tmp_path: Path) -> None:
    def edit(ev: Event, sim: SimFleet, state: FleetState) -> None:
        d = mission_dict()
        d["tasks"].append({"id": "t9", "position": [0, 50, 400]})  # higher than deploy_range
        (tmp_path / "mission.yaml").write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")

    s, trig, sim, _ = await fly(tmp_path, mission_dict(), "deploy", once("stop_reached", edit))
    rejected = [e for e in trig.events if e.kind == "task_change_rejected"]
    assert rejected and "tasks[5]" in rejected[0].text
    assert s["_exit"] == 0 and s["replans"] == 0 and s["tasks_reached"] == TASK_IDS
    assert_accounted(s, TASK_IDS, ROVERS7)


async def test_rover_lost_flying_to_its_meeting_point_is_removed(tmp_path: Path) -> None:
    def drop(ev: Event, sim: SimFleet, state: FleetState) -> None:
        asyncio.get_running_loop().call_later(0.2, sim.dropout, "r2")

    s, trig, sim, _ = await fly(tmp_path, mission_dict(rovers=5), "run", once("collection_started", drop),
                                dwell=2.0)
    assert s["tasks_reached"] == TASK_IDS
    assert "r2" in s["rovers_lost"] and "r2" not in s["rovers_loaded"]
    assert sorted(s["rovers_loaded"] + ["r2"]) == ROVERS7[:5]
    assert_accounted(s, TASK_IDS, ROVERS7[:5])


async def test_run_with_packet_loss_and_latency(tmp_path: Path) -> None:
    d = mission_dict(rovers=5, faults=[{"kind": "packet_loss", "rate": 0.2},
                                       {"kind": "latency", "seconds": 0.2}])
    # 1 Hz heartbeats, 20 % loss and 200 ms latency: two lost heartbeats in a row already outlast a
    # 3 s timeout (p = 0.04 per beat, several flaps per run on a loaded machine); a link this lossy
    # wants a longer timeout, and this test is about flying through the loss, not about dropouts
    d["links"]["heartbeat_timeout"] = 8.0
    s, trig, sim, _ = await fly(tmp_path, d, "run", dwell=2.0)
    assert s["_exit"] == 0, s
    assert s["tasks_reached"] == TASK_IDS and sorted(s["rovers_loaded"]) == ROVERS7[:5]
    assert_accounted(s, TASK_IDS, ROVERS7[:5])


async def test_a_rover_back_within_reassign_after_keeps_its_task(tmp_path: Path) -> None:
    """A flapping link: the autopilot flies on; the task is not handed to a spare."""
    victim: list[str] = []

    def action(ev: Event, sim: SimFleet, state: FleetState) -> None:
        if not victim and ev.kind == "rover_launched" and ev.data.get("stop", 0) >= 2:
            victim.append(ev.vehicle or "")
            # 24 mission s (3 wall s): lost after 8 (the 1 wall s floor), back at 24, within the grace
            sim.dropout(ev.vehicle or "", duration=3.0 * SPEEDUP)

    s, trig, sim, _ = await fly(tmp_path, mission_dict(reassign_after=40.0), "deploy", action)
    assert victim and s["_exit"] == 0, s
    kinds = [(e.kind, e.vehicle) for e in trig.events]
    assert ("link_lost", victim[0]) in kinds
    assert not [e for e in trig.events if e.kind == "task_returned"], "the task went to a spare"
    task = next(t for t, r in s["assignment"].items() if r == victim[0])
    reached = [e for e in trig.events if e.kind == "task_reached" and e.data.get("task") == task]
    assert reached and reached[0].vehicle == victim[0]  # reached by the rover that was lost a while
    rec = [r for r in journal(s) if r.get("kind") == "reassign_pending"]
    assert rec and rec[0]["vehicle"] == victim[0] and rec[0]["after"] == 40.0
    assert_accounted(s, TASK_IDS, ROVERS7)


async def test_a_rover_whose_battery_empties_gives_its_task_back_at_once(tmp_path: Path) -> None:
    victim: list[str] = []

    def action(ev: Event, sim: SimFleet, state: FleetState) -> None:
        if not victim and ev.kind == "rover_launched" and ev.data.get("stop", 0) >= 1:
            victim.append(ev.vehicle or "")
            loop = asyncio.get_running_loop()
            loop.call_later(0.3, setattr, sim.rover(ev.vehicle or ""), "battery", 0.0)  # lands where it is

    s, trig, sim, _ = await fly(tmp_path, mission_dict(), "deploy", action)
    assert victim and s["_exit"] == 0, s
    returned = [e for e in trig.events if e.kind == "task_returned"]
    assert returned and returned[0].vehicle == victim[0] and "battery empty" in returned[0].text
    task = returned[0].data["task"]
    assert task in s["tasks_reached"] and s["assignment"][task] != victim[0]
    assert not [e for e in trig.events if e.kind == "task_timeout"]
    assert_accounted(s, TASK_IDS, ROVERS7)
