"""The controller flying missions against the simulated fleet over real UDP (fleetctl.run.executor):
recon.yaml deployment then collection (``run``), packet loss, a rover that refuses to arm,
collection of field-placed rovers, errors users meet, the records of a run and the CLI.

Flown vs planned makespan (simulated seconds) - the tolerance and why:
the simulated vehicles move by the planners' time model, except that a rover takes off
*vertically* to its task height and then flies level to the task (docs/mavlink.md, the mission items:
NAV_TAKEOFF to the task height, then NAV_WAYPOINT), while the plan charges the straight 3D line.
That costs each rover ``z + h - sqrt(z² + h²)`` over its speed (z = task height, h = horizontal
distance). On top of it the controller only sees the world through telemetry (10 Hz wall, i.e.
every ``speedup / 10`` simulated seconds) and reacts with command round trips. So::

    planned - unload_time - 1 s  <=  flown  <=  planned + max_i vertical_penalty_i + 5 % + 3 telemetry periods

Lower side: the controller launches a stop's rovers as soon as the carrier is there (the carrier
still holds for ``unload_time``), while the time model lets them depart when unloading ends; and
the carrier starts on the command, a moment before its ACK starts our clock.

Collection is slower than its plan by design of the protocol: a rover that arrives first cannot
sit on a carrier that is not there yet, so it waits ``COLLECT_MEET_HEIGHT`` (3 m) above the stop
and descends only when the carrier has stopped (the time model loads it at once); the controller
then sees the touchdown one telemetry period later and starts ``load_time``. Per stop::

    planned - 1 s  <=  flown  <=  planned + stops x (3 m / rover speed + 2 telemetry periods) + 5 %
"""

from __future__ import annotations

import asyncio
import json
import math
import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavutil

from fleetctl.mavlink.fleet import Fleet
from fleetctl.mission import Mission, load_mission
from fleetctl.run.flight import execute
from fleetctl.run.planning import COLLECT_MEET_HEIGHT
from fleetctl.run.sim import sim_mission_dict
from fleetctl.run.state import FleetState
from fleetctl.views.dashboard import render
from fleetctl.views.view import View
from sitl import FleetConfig, SimFleet
from tests.run.ctl_helpers import mission_dict, mission_from, write_mission

ROOT = Path(__file__).resolve().parents[2]
RECON = ROOT / "missions" / "recon.yaml"
SPEEDUP = 20.0
POSITION_HZ = 10.0  # fleetctl.mavlink.vehicle.DEFAULT_POSITION_HZ (wall)


class Probe(View):
    """A view that looks at the simulated world when the deployment completes."""

    def __init__(self, sim: SimFleet) -> None:
        self.sim = sim
        self.at_deploy: dict[str, tuple[float, float, float]] = {}
        self.on_ground_at_deploy: dict[str, bool] = {}
        self.state: FleetState | None = None
        self.link_stats: dict[str, int] = {}

    def start(self, state: FleetState, fleet: Fleet | None) -> None:
        if self.state is None:
            self.state = state
            state.add_listener(self._on_event)

    def _on_event(self, ev: Any) -> None:
        if ev.kind == "deployed":
            for rid, body in self.sim.world.rovers.items():
                self.at_deploy[rid] = body.position
                self.on_ground_at_deploy[rid] = body.on_ground

    async def stop(self) -> None:
        pass


def vertical_penalty(plan: dict[str, Any], speed: float) -> float:
    """Largest extra time of take-off-then-level flight over the planned straight 3D line."""
    worst = 0.0
    for stop in plan["stops"]:
        for r in stop["rovers"]:
            (x0, y0, _), (x, y, z) = r["path"][0], r["target"]
            h = math.hypot(x - x0, y - y0)
            worst = max(worst, (z + h - math.hypot(z, h)) / speed)
    return worst


def assert_makespan_within_tolerance(planned: float, flown: float, plan: dict[str, Any], speed: float,
                                     speedup: float, unload_time: float) -> None:
    upper = planned + vertical_penalty(plan, speed) + 0.05 * planned + 3 * speedup / POSITION_HZ
    assert planned - unload_time - 1.0 <= flown <= upper, (planned, flown, upper)


def journal(run_dir: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (run_dir / "journal.jsonl").read_text().splitlines()]


async def fly(mission: Mission, command: str, tmp_path: Path, d: dict[str, Any] | None = None,
              autopilot: str | None = None, **kw: Any) -> tuple[Any, SimFleet, Probe]:
    cfg = FleetConfig.from_mission_dict(d if d is not None else sim_mission_dict(mission), speedup=SPEEDUP,
                                        autopilot=autopilot)
    async with SimFleet(cfg) as sim:
        probe = Probe(sim)
        out = await execute(mission, command, sim=sim, runs_dir=tmp_path / "runs", view=probe, **kw)
        probe.link_stats = sim.link_stats()
        assert sim.errors == 0, sim.last_error
    return out, sim, probe


@pytest.mark.slow
async def test_recon_run_deploys_then_collects_every_rover(tmp_path: Path) -> None:
    mission = load_mission(RECON)
    out, sim, probe = await fly(mission, "run", tmp_path, dwell=10.0, summary_path=tmp_path / "s.json")
    s = out.summary
    assert out.exit_code == 0, (out.error, s)
    task_ids = [t.id for t in mission.tasks]
    # deployment: every task reached, each rover hovering within 1 m of its task at its height
    assert s["tasks_reached"] == task_ids and s["tasks_unserved"] == []
    assignment = s["assignment"]
    assert sorted(assignment) == sorted(task_ids) and len(set(assignment.values())) == len(task_ids)
    for task in mission.tasks:
        pos = probe.at_deploy[assignment[task.id]]
        assert math.dist(pos, task.position) <= 1.0, (task.id, pos, task.position)
        assert abs(pos[2] - task.position[2]) <= 1.0
        assert not probe.on_ground_at_deploy[assignment[task.id]]
    # collection: every deployed rover is back on the carrier (simulated world)
    assert sorted(s["rovers_loaded"]) == sorted(assignment.values())
    for rid in assignment.values():
        assert sim.rover(rid).loaded, rid
    assert s["rovers_lost"] == [] and s["result"] == "complete" and s["phase"] == "run"
    # flown vs planned makespan of the deployment (module docstring)
    plan = json.loads((out.run_dir / "plan.json").read_text())
    dep = s["phases"]["deploy"]
    assert_makespan_within_tolerance(dep["planned"], dep["flown"], plan, mission.rovers.max_speed, SPEEDUP,
                                     mission.carrier.unload_time)
    col = s["phases"]["collect"]
    cplan = json.loads((out.run_dir / "plan-collect.json").read_text())
    per_stop = COLLECT_MEET_HEIGHT / mission.rovers.max_speed + 2 * SPEEDUP / POSITION_HZ
    upper = col["planned"] + len(cplan["stops"]) * per_stop + 0.05 * col["planned"]
    assert col["planned"] - 1.0 <= col["flown"] <= upper, (col, upper)
    assert json.loads((tmp_path / "s.json").read_text()) == s
    # records
    assert (out.run_dir / "plan-collect.json").exists()
    kinds = [r["kind"] for r in journal(out.run_dir)]
    for kind in ("plan", "command", "ack", "stop_reached", "rover_launched", "task_reached", "rover_loaded",
                 "summary"):
        assert kind in kinds, kind
    assert kinds.count("task_reached") == len(task_ids) and kinds.count("rover_loaded") == len(task_ids)
    # every rover loaded: the carrier is left in HOLD and disarmed (the next preflight takes it)
    parked = [r for r in journal(out.run_dir) if r["kind"] == "carrier_parked"]
    assert len(parked) == 1 and parked[0]["disarmed"] is True, parked
    assert kinds.index("carrier_parked") > max(i for i, k in enumerate(kinds) if k == "rover_loaded")


async def test_deploy_records_tlog_plan_journal_and_summary(tmp_path: Path) -> None:
    d = mission_dict(rovers=3)
    mission = mission_from(d, tmp_path)
    out, _sim, _probe = await fly(mission, "deploy", tmp_path, d)
    assert out.exit_code == 0, out.error
    run_dir = out.run_dir
    assert run_dir.parent == tmp_path / "runs" and run_dir.name.startswith("ctltest-")
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary == out.summary
    assert summary["schema"] == "fleetctl.summary/1" and summary["mission"] == "ctltest"
    assert summary["phase"] == "deploy" and summary["result"] == "complete" and summary["replans"] == 0
    assert summary["tasks_reached"] == ["t1", "t2"] and summary["makespan_flown"] > 0
    assert Path(summary["journal"]) == run_dir / "journal.jsonl"
    plan = json.loads((run_dir / "plan.json").read_text())
    assert plan["schema"] == "fleetctl.plan/1" and plan["kind"] == "deploy"
    assert summary["makespan_planned"] == pytest.approx(plan["makespan"], abs=1e-3)
    assert {r["task"] for s in plan["stops"] for r in s["rovers"]} == {"t1", "t2"}
    records = journal(run_dir)
    acks = [r for r in records if r["kind"] == "ack"]
    commands = [r for r in records if r["kind"] == "command"]
    assert len(acks) == len(commands) and all(a["result"] == "MAV_RESULT_ACCEPTED" for a in acks)
    assert {"upload_mission", "arm", "start_mission"} <= {c["command"] for c in commands}
    if len(plan["stops"]) > 1:  # the carrier is released from every stop but the last
        assert "set_current" in {c["command"] for c in commands}
    stops = [r for r in records if r["kind"] == "stop_reached"]
    assert [r["stop"] for r in stops] == list(range(1, len(plan["stops"]) + 1))
    reached = {r["task"]: r for r in records if r["kind"] == "task_reached"}
    assert set(reached) == {"t1", "t2"}
    # the tlog: pymavlink reads it, in both directions
    conn = mavutil.mavlink_connection(str(run_dir / "traffic.tlog"))
    types: dict[str, int] = {}
    sources: set[int] = set()
    while (msg := conn.recv_match()) is not None:
        types[msg.get_type()] = types.get(msg.get_type(), 0) + 1
        sources.add(msg.get_srcSystem())
    assert types.get("HEARTBEAT", 0) > 0 and types.get("GLOBAL_POSITION_INT", 0) > 0
    assert types.get("MISSION_ITEM_INT", 0) > 0
    assert types.get("COMMAND_LONG", 0) + types.get("COMMAND_INT", 0) > 0
    assert {1, 11, 12, 255} <= sources


@pytest.mark.slow
async def test_deployment_completes_with_ten_percent_packet_loss(tmp_path: Path) -> None:
    d = mission_dict(rovers=3, faults=[{"kind": "packet_loss", "rate": 0.1}])
    d["tasks"] = [{"id": "t1", "position": [20, 10, 5]}, {"id": "t2", "position": [40, -10, 4]},
                  {"id": "t3", "position": [10, 30, 3]}]
    mission = mission_from(d, tmp_path)
    out, sim, probe = await fly(mission, "deploy", tmp_path, d)
    assert out.exit_code == 0, out.error
    assert out.summary["tasks_reached"] == ["t1", "t2", "t3"]
    for task in mission.tasks:
        assert math.dist(sim.rover(out.summary["assignment"][task.id]).position, task.position) <= 1.0
    stats = probe.link_stats
    assert stats["rx_lost"] > 0 and stats["tx_lost"] > 0  # the loss really happened, both ways


async def test_rover_refusing_to_arm_is_replaced_by_a_spare(tmp_path: Path) -> None:
    d = mission_dict(rovers=3, faults=[{"vehicle": "r1", "kind": "refuse_arm"}])
    mission = mission_from(d, tmp_path)
    out, sim, _probe = await fly(mission, "deploy", tmp_path, d)
    s = out.summary
    assert out.exit_code == 0, out.error
    assert s["tasks_reached"] == ["t1", "t2"]
    assert "r1" not in s["assignment"].values() and "r3" in s["assignment"].values()
    assert s["substitutions"] and s["substitutions"][0]["refused"] == "r1"
    assert s["substitutions"][0]["spare"] == "r3"
    assert sim.rover("r1").loaded  # still on the deck
    refused = [r for r in journal(out.run_dir) if r["kind"] == "rover_refused"]
    assert refused and refused[0]["vehicle"] == "r1" and refused[0]["spare"] == "r3"
    assert "Arming denied" in refused[0]["reason"]
    for task in mission.tasks:
        assert math.dist(sim.rover(s["assignment"][task.id]).position, task.position) <= 1.0


async def test_collect_on_sim_places_rovers_from_the_collection_section(tmp_path: Path) -> None:
    d = mission_dict(rovers=3)
    d["collection"] = {"rovers": [{"id": "r1", "position": [20, 10, 5], "range": 300.0},
                                  {"id": "r2", "position": [35, -12, 4], "range": 250.0}]}
    mission = mission_from(d, tmp_path)
    out = await execute(mission, "collect", speedup=SPEEDUP, runs_dir=tmp_path / "runs")
    s = out.summary
    assert out.exit_code == 0, out.error
    assert s["phase"] == "collect" and s["result"] == "complete"
    assert sorted(s["rovers_loaded"]) == ["r1", "r2"] and s["tasks_reached"] == []
    states = [r for r in journal(out.run_dir) if r["kind"] == "rover_state"]
    assert {r["vehicle"] for r in states} == {"r1", "r2"}
    # the simulated batteries carry the mission's ranges: range = (remaining - reserve) x endurance
    by_id = {r["vehicle"]: r for r in states}
    # (the battery reads in whole percent: 1 % of the endurance)
    assert by_id["r2"]["range"] == pytest.approx(250.0, abs=0.01 * mission.rovers.endurance_range + 0.5)
    assert s["makespan_flown"] >= s["makespan_planned"] - 1.0


async def test_collect_leaves_a_rover_without_range_to_land_and_says_so(tmp_path: Path) -> None:
    d = mission_dict(rovers=3)
    d["collection"] = {"rovers": [{"id": "r1", "position": [20, 10, 5], "range": 60.0},
                                  {"id": "r2", "position": [35, -12, 12], "range": 6.0}]}
    mission = mission_from(d, tmp_path)
    out = await execute(mission, "collect", speedup=SPEEDUP, runs_dir=tmp_path / "runs")
    s = out.summary
    assert out.exit_code == 0, out.error  # every *reachable* rover loaded
    assert s["rovers_loaded"] == ["r1"] and s["rovers_unreachable"] == ["r2"]
    events = [r for r in journal(out.run_dir) if r["kind"] == "rover_unreachable"]
    assert [r["vehicle"] for r in events] == ["r2"]


async def test_collect_on_sim_without_collection_section_is_refused(tmp_path: Path) -> None:
    mission = mission_from(mission_dict(), tmp_path)
    proc = await asyncio.to_thread(
        subprocess.run, [sys.executable, "-m", "fleetctl.cli", "collect", "--mission", str(mission.path)],
        cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert "collection:" in proc.stderr and "fleetctl run" in proc.stderr


async def test_vehicle_that_never_answers_is_named_with_its_url(tmp_path: Path) -> None:
    from tests.run.ctl_helpers import free_udp_port

    url = f"udp://127.0.0.1:{free_udp_port()}"
    mission = mission_from(mission_dict(carrier_connection=url), tmp_path)
    out = await execute(mission, "deploy", runs_dir=tmp_path / "runs", connect_timeout=1.0)
    assert out.exit_code == 1
    assert out.error is not None and "carrier" in out.error and url in out.error
    assert out.summary["result"] == "incomplete" and out.summary["tasks_unserved"] == ["t1", "t2"]
    assert "error" in out.summary


def test_dashboard_renders_a_row_per_vehicle(tmp_path: Path) -> None:
    from rich.console import Console

    mission = mission_from(mission_dict(rovers=2), tmp_path)
    state = FleetState(mission)
    state.set_phase("deploy", 42.0, 3)
    state.stop_index = 2
    state.set_state("r1", "en_route", task="t1")
    state.vehicles["r1"].enu = (12.5, -3.0, 4.0)
    state.vehicles["r1"].battery_pct = 87.0
    state.vehicles["r1"].range_m = 46.2
    state.event("stop_reached", "carrier: stop 2/3 reached", "carrier")
    console = Console(record=True, width=120)
    console.print(render(state))
    text = console.export_text()
    assert "stop 2/3" in text and "planned 42.0 s" in text and "deploy" in text
    row = next(line for line in text.splitlines() if line.startswith("r1"))
    assert "en_route" in row and "t1" in row and "12.5" in row and "87" in row and "46" in row
    assert any(line.startswith("r2") for line in text.splitlines())
    assert "carrier: stop 2/3 reached" in text


@pytest.mark.slow
def test_cli_deploy_recon_headless_exits_zero_and_accounts_for_every_task(tmp_path: Path) -> None:
    out = tmp_path / "s.json"
    proc = subprocess.run(
        [sys.executable, "-m", "fleetctl.cli", "deploy", "--headless", "--speedup", "20",
         "--mission", str(RECON), "--summary", str(out)],
        cwd=tmp_path, capture_output=True, text=True, timeout=170)
    assert proc.returncode == 0, proc.stderr[-2000:]
    s = json.loads(out.read_text())
    mission = load_mission(RECON)
    assert sorted(s["tasks_reached"] + s["tasks_unserved"]) == sorted(t.id for t in mission.tasks)
    assert s["tasks_unserved"] == [] and s["result"] == "complete"
    lines = proc.stdout.splitlines()
    assert sum("task_reached" in line for line in lines) == len(mission.tasks)
    assert Path(tmp_path / s["journal"]).exists() or Path(s["journal"]).exists()


@pytest.mark.slow
def test_cli_ctrl_c_holds_rovers_writes_summary_and_exits_130(tmp_path: Path) -> None:
    d = mission_dict(rovers=2, speedup=2.0)
    path = write_mission(d, tmp_path / "slow.yaml")
    out = tmp_path / "s.json"
    proc = subprocess.Popen(
        [sys.executable, "-m", "fleetctl.cli", "deploy", "--headless", "--mission", str(path),
         "--summary", str(out)],
        cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            if "rover_launched" in line:
                break
        os.kill(proc.pid, signal.SIGINT)
        _stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, stderr[-2000:]
    s = json.loads(out.read_text())
    assert s["result"] == "interrupted"
    records = journal(Path(s["journal"]).parent if Path(s["journal"]).is_absolute()
                      else tmp_path / Path(s["journal"]).parent)
    hold = [r for r in records if r["kind"] == "hold"]
    assert hold and "r1" in hold[0]["vehicles"]
    assert any(r["kind"] == "command" and r["command"] == "hold" and r["vehicle"] == "r1" for r in records)


@pytest.mark.slow
async def test_link_lost_and_back_are_journaled_and_the_run_still_completes(tmp_path: Path) -> None:
    # the spare r3 stays on the deck and goes silent during the dwell for longer than the
    # heartbeat timeout (3 s wall = 60 simulated s at 20x), then comes back; connect, preflight and
    # the deployment take about 100 simulated s
    d = mission_dict(rovers=3, faults=[{"vehicle": "r3", "kind": "dropout", "at": 160.0, "until": 250.0}])
    d["dwell"] = 220.0
    d["rovers"]["endurance_range"] = 3000.0  # 10 min at 5 m/s: the rovers hover through the dwell
    mission = mission_from(d, tmp_path)
    out, sim, _probe = await fly(mission, "run", tmp_path, d)
    assert out.exit_code == 0, out.error
    assert sorted(out.summary["rovers_loaded"]) == ["r1", "r2"] and out.summary["rovers_lost"] == []
    records = journal(out.run_dir)
    lost = [r for r in records if r["kind"] == "link_lost"]
    back = [r for r in records if r["kind"] == "link_back"]
    assert [r["vehicle"] for r in lost] == ["r3"] and [r["vehicle"] for r in back] == ["r3"]
    assert lost[0]["elapsed"] < back[0]["elapsed"]
    assert sim.rover("r3").loaded


async def test_run_on_ardupilot_flavoured_vehicles(tmp_path: Path) -> None:
    # ArduPilot: mission item 0 is home, GUIDED/AUTO modes, MISSION_START
    d = mission_dict(rovers=3)
    d["dwell"] = 5.0
    mission = mission_from(d, tmp_path)
    out, sim, _probe = await fly(mission, "run", tmp_path, d, autopilot="ardupilot")
    assert out.exit_code == 0, out.error
    assert out.summary["tasks_reached"] == ["t1", "t2"]
    assert sorted(out.summary["rovers_loaded"]) == sorted(out.summary["assignment"].values())
    assert all(sim.rover(r).loaded for r in out.summary["rovers_loaded"])
    rows = journal(out.run_dir)
    connected = [r for r in rows if r["kind"] == "connected"]
    assert {r["autopilot"] for r in connected} == {"ardupilot"}
    # over their stop, ArduCopter rovers come down in LAND mode, not by their mission's NAV_LAND
    # (which would first fly to the item and settle: Autopilot.mission_landing_settles)
    k = next(i for i, r in enumerate(rows) if r["kind"] == "phase" and r["phase"] == "collect")
    landing = [(r["vehicle"], r["command"]) for r in rows[k:]
               if r["kind"] == "command" and r["vehicle"] != "carrier"]
    assert {v for v, c in landing if c == "land"} == set(out.summary["rovers_loaded"])
    assert not [v for v, c in landing if c == "set_current"]
