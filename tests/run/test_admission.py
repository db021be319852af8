"""Before arming: fly with the rovers that answer, one controller per fleet, arming real aircraft
only on a decision. Real MAVLink over UDP against the simulated fleet."""

from __future__ import annotations

import asyncio
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

from fleetctl.run.flight import execute
from fleetctl.run.sim import sim_mission_dict
from fleetctl.run.state import Event, FleetState
from fleetctl.views.view import View
from sitl import FleetConfig, SimFleet
from tests.run.ctl_helpers import mission_dict, mission_from, write_mission

ROOT = Path(__file__).resolve().parents[2]


def _dead_rover_mission(tmp_path: Path, rovers: int = 4) -> Any:
    d = mission_dict(rovers=rovers, faults=[{"vehicle": "r2", "kind": "dropout", "at": 0.0}])
    return mission_from(d, tmp_path)


async def test_a_dead_rover_at_connect_is_left_out_and_the_spares_fly(tmp_path: Path) -> None:
    mission = _dead_rover_mission(tmp_path)
    out = await asyncio.wait_for(execute(mission, "deploy", runs_dir=tmp_path / "runs", connect_timeout=3.0),
                                 120)
    s = out.summary
    assert out.exit_code == 0, s
    assert sorted(s["tasks_reached"]) == ["t1", "t2"]
    assert "r2" in s["rovers_lost"] and "did not answer at connect" in s["rovers_lost_reasons"]["r2"]
    assert "r2" not in s["assignment"].values()
    kinds = [line for line in (out.run_dir / "journal.jsonl").read_text().splitlines() if '"missing"' in line]
    assert kinds and '"r2"' in kinds[0]


async def test_require_all_refuses_a_fleet_with_a_dead_rover(tmp_path: Path) -> None:
    mission = _dead_rover_mission(tmp_path)
    out = await asyncio.wait_for(execute(mission, "deploy", runs_dir=tmp_path / "runs", connect_timeout=2.0,
                                         require_all=True), 60)
    assert out.exit_code == 1
    assert out.error is not None and "r2" in out.error and "--require-all" in out.error
    assert out.summary["tasks_reached"] == []


async def test_too_few_rovers_answering_for_the_tasks_is_an_error(tmp_path: Path) -> None:
    mission = _dead_rover_mission(tmp_path, rovers=2)  # 2 tasks, r2 dead
    out = await asyncio.wait_for(execute(mission, "deploy", runs_dir=tmp_path / "runs", connect_timeout=2.0),
                                 60)
    assert out.exit_code == 1 and out.error is not None
    assert "only 1 rover(s) answered for 2 tasks" in out.error and "r2" in out.error


class _OnEvent(View):
    def __init__(self, kind: str, then: Any) -> None:
        self.kind, self.then, self.done = kind, then, False

    def start(self, state: FleetState, fleet: Any) -> None:
        def on(ev: Event) -> None:
            if ev.kind == self.kind and not self.done:
                self.done = True
                self.then()

        if fleet is None:
            state.add_listener(on)


async def test_a_second_controller_is_refused_while_the_first_completes(tmp_path: Path) -> None:
    mission = mission_from(mission_dict(rovers=3), tmp_path)
    cfg = FleetConfig.from_mission_dict(sim_mission_dict(mission), speedup=20.0)
    second: list[Any] = []
    async with SimFleet(cfg) as sim:
        def start_second() -> None:
            second.append(asyncio.ensure_future(execute(mission, "deploy", endpoints=dict(sim.endpoints),
                                                        runs_dir=tmp_path / "runs2", connect_timeout=3.0)))

        view = _OnEvent("carrier_started", start_second)
        first = await asyncio.wait_for(execute(mission, "deploy", sim=sim, runs_dir=tmp_path / "runs1",
                                               view=view), 120)
        assert second, "the second controller was never started"
        other = await asyncio.wait_for(second[0], 60)
    assert first.exit_code == 0, first.summary
    assert other.exit_code == 1 and other.error is not None
    assert "another controller" in other.error and "fleetctl resume" in other.error
    assert "ground station" in other.error or "armed" in other.error
    assert other.summary["tasks_reached"] == []


def test_real_vehicles_are_not_armed_without_a_terminal_or_yes(tmp_path: Path) -> None:
    d = mission_dict(rovers=2, carrier_connection="udp://127.0.0.1:9")
    path = write_mission(d, tmp_path / "real.yaml")
    proc = subprocess.run([sys.executable, "-m", "fleetctl.cli", "deploy", "--headless",
                           "--mission", str(path)],
                          cwd=tmp_path, capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL,
                          env=os.environ | {"PYTHONPATH": str(ROOT)})
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    assert "--yes" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "runs").exists()  # refused before anything was started


async def test_collect_reports_a_rover_that_does_not_answer_and_collects_the_rest(tmp_path: Path) -> None:
    d = mission_dict(rovers=3, faults=[{"vehicle": "r2", "kind": "dropout", "at": 0.0}])
    d["collection"] = {"rovers": [{"id": "r1", "position": [20, 10, 5], "range": 300.0},
                                  {"id": "r2", "position": [35, -12, 4], "range": 225.0},
                                  {"id": "r3", "position": [-10, 25, 3], "range": 250.0}]}
    mission = mission_from(d, tmp_path)
    out = await asyncio.wait_for(execute(mission, "collect", runs_dir=tmp_path / "runs", connect_timeout=3.0),
                                 120)
    s = out.summary
    assert out.exit_code == 0, (out.error, s)
    assert sorted(s["rovers_loaded"]) == ["r1", "r3"]
    assert s["rovers_lost"] == ["r2"] and "did not answer at connect" in s["rovers_lost_reasons"]["r2"]
