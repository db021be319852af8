"""One preflight: `fleetctl status` and the flying commands run the same checks
(fleetctl.run.preflight, system status and position included), the real reason first; `status
--json` prints one object per vehicle with every check; without a terminal the table is plain,
uncut lines. Real MAVLink over UDP against the simulated fleet."""

from __future__ import annotations

import asyncio
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from fleetctl.cli import main
from fleetctl.mavlink.fleet import connect_fleet
from fleetctl.run.flight import execute
from fleetctl.run.preflight import CHECKS, check_connected, check_fleet
from fleetctl.run.safety import gather
from fleetctl.views.status import json_objects, not_ready_report, plain_lines, status_rows
from tests.run.ctl_helpers import mission_dict, mission_from, sim_fleet, write_mission

ROOT = Path(__file__).resolve().parents[2]


def _low_battery_mission() -> dict:
    d = mission_dict(rovers=3, speedup=10.0, faults=[{"vehicle": "r2", "kind": "low_battery", "level": 0.05},
                                                      {"vehicle": "r3", "kind": "low_battery", "level": 0.2}])
    d["rovers"]["endurance_range"] = 200.0  # r3: (0.2 - 0.1) x 200 = 20 m < deploy_range 40 m
    return d


def test_status_json_prints_one_object_per_vehicle_with_every_check(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_mission(_low_battery_mission(), tmp_path / "m.yaml")
    rc = main(["status", "--mission", str(path), "--timeout", "5", "--json"])
    cap = capsys.readouterr()
    assert rc == 1
    objs = [json.loads(line) for line in cap.out.splitlines()]  # nothing but JSON on stdout
    by = {o["vehicle"]: o for o in objs}
    assert list(by) == ["carrier", "r1", "r2", "r3"]
    for o in objs:
        assert [c["name"] for c in o["checks"]] == list(CHECKS)
    assert by["r1"]["ready"] and by["r1"]["range_m"] == 40.0 and by["r1"]["on_deck"] is True
    assert not by["r2"]["ready"] and by["r2"]["reasons"] == ["battery 5 % is not above the reserve 10%"]
    assert [c["name"] for c in by["r2"]["checks"] if not c["ok"]] == ["battery"]
    assert by["r3"]["ready"] and by["r3"]["range_m"] == 20.0 and by["r3"]["deploy_range_m"] == 40.0
    assert by["carrier"]["role"] == "carrier" and by["carrier"]["system_status"] == 3
    # the real reason first; no connection hint when every vehicle answers
    assert cap.err.startswith("fleetctl: 1 vehicle(s) not ready (r2 battery):"), cap.err
    assert "no heartbeat" not in cap.err and "check the URL" not in cap.err


def test_status_without_a_terminal_prints_plain_uncut_lines(tmp_path: Path) -> None:
    path = write_mission(_low_battery_mission(), tmp_path / "m.yaml")
    proc = subprocess.run(
        [sys.executable, "-m", "fleetctl.cli", "status", "--mission", str(path), "--timeout", "5"],
        cwd=tmp_path, capture_output=True, text=True, timeout=60,
        env=os.environ | {"PYTHONPATH": str(ROOT), "COLUMNS": "40"},  # a narrow "terminal" cuts nothing
    )
    assert proc.returncode == 1, proc.stderr
    lines = [ln for ln in proc.stdout.splitlines() if "\t" in ln]
    header, rows = lines[0].split("\t"), [ln.split("\t") for ln in lines[1:]]
    assert header[0] == "vehicle" and header[-1] == "why not ready" and len(rows) == 4
    assert all(len(r) == len(header) for r in rows)
    cells = {r[0]: dict(zip(header, r, strict=True)) for r in rows}
    assert cells["carrier"]["role"] == "carrier" and cells["r1"]["armed"] == "disarmed"
    assert cells["r1"]["ready"] == "ready" and cells["r2"]["ready"] == "no"
    assert cells["r2"]["why not ready"] == "battery 5 % is not above the reserve 10%"
    assert cells["r3"]["battery"] == "20 % (20 m range)" and cells["r3"]["ready"] == "ready"
    assert "…" not in proc.stdout and "│" not in proc.stdout


async def test_system_status_and_position_are_checked_for_every_command(tmp_path: Path) -> None:
    d = mission_dict(rovers=3)
    mission = mission_from(d, tmp_path)
    async with sim_fleet(d) as sim, await connect_fleet(mission, sim.endpoints, timeout=5.0) as fleet:
        await gather(fleet)
        fleet.rovers["r1"].system_status = 6  # MAV_STATE_EMERGENCY
        fleet.rovers["r2"].lat = None  # no GLOBAL_POSITION_INT (no await below: telemetry cannot undo it)
        fleet.rovers["r3"].system_status = 5  # MAV_STATE_CRITICAL: a warning
        by_command = {cmd: check_fleet(fleet.vehicles, fleet.carrier_id, mission, command=cmd)
                      for cmd in (None, "deploy", "collect", "run")}
        by_command["resume"] = check_fleet(fleet.vehicles, fleet.carrier_id, mission, command="run",
                                           resuming=True)
        status = check_connected(fleet, mission)
        cells = status_rows(mission, fleet, status)
        report = not_ready_report(fleet, status)
    for rows in by_command.values():
        assert rows["r1"].failures[0] == "system status emergency (MAV_STATE 6)"
        assert rows["r2"].failures[0] == "no position (GLOBAL_POSITION_INT) received"
        assert rows["r3"].ok
        assert rows["r3"].warnings == ["system status critical (an autopilot failsafe is active)"]
    assert {vid: r.failures for vid, r in status.items()} == {
        vid: r.failures for vid, r in by_command[None].items()}
    assert [c["reasons"] for c in cells] == ["", "system status emergency (MAV_STATE 6)",
                                            "no position (GLOBAL_POSITION_INT) received", ""]
    assert report[0] == "fleetctl: 2 vehicle(s) not ready (r1 system, r2 position):"
    assert not any("no heartbeat" in line for line in report)


async def test_a_vehicle_that_does_not_answer_fails_heartbeat_alone_with_the_hint(tmp_path: Path) -> None:
    d = mission_dict(rovers=2)
    mission = mission_from(d, tmp_path)
    served = mission_dict(rovers=1)
    async with sim_fleet(served) as sim:
        fleet = await connect_fleet(mission, sim.endpoints, timeout=1.0, require_all=False)
        try:
            await gather(fleet)
            rows = check_connected(fleet, mission)
            objs = json_objects(mission, fleet, rows)
            report = not_ready_report(fleet, rows)
            lines = plain_lines(status_rows(mission, fleet, rows))
        finally:
            await fleet.close()
    assert [c.name for c in rows["r2"].checks] == ["heartbeat"] and not rows["r2"].ok
    assert rows["r2"].failures[0].startswith("no heartbeat within 1 s")
    r2 = next(o for o in objs if o["vehicle"] == "r2")
    assert r2["connected"] is False and r2["ready"] is False and r2["battery_pct"] is None
    assert report[0] == "fleetctl: 1 vehicle(s) not ready (r2 heartbeat):"
    assert report[-1].startswith("  no heartbeat: check the URL")
    assert lines[-1].startswith("r2\trover\t12\t") and "\tno answer\t" in lines[-1]


async def test_a_rover_short_of_the_deploy_range_flies_a_task_it_reaches(tmp_path: Path) -> None:
    # r1 has 20 m of its 40 m deploy range, r2 2 m: less than the 3 m the lowest task needs above
    # the take-off height (t2 is 4 m high): r2 fails preflight, r1 and r3 fly, r1 within 20 m
    d = mission_dict(rovers=3, faults=[{"vehicle": "r1", "kind": "low_battery", "level": 0.2},
                                       {"vehicle": "r2", "kind": "low_battery", "level": 0.11}])
    d["rovers"]["endurance_range"] = 200.0
    mission = mission_from(d, tmp_path)
    out = await asyncio.wait_for(execute(mission, "deploy", runs_dir=tmp_path / "runs"), 120)
    s = out.summary
    assert out.exit_code == 0, (out.error, s)
    assert sorted(s["tasks_reached"]) == ["t1", "t2"] and set(s["assignment"].values()) == {"r1", "r3"}
    assert s["rovers_lost_reasons"]["r2"] == (
        "failed preflight: battery 11 % gives 2 m above the reserve, less than the deploy range 40 m "
        "(needs 30 %): it reaches no task (the nearest needs 3.0 m)")
    records = [json.loads(line) for line in (out.run_dir / "journal.jsonl").read_text().splitlines()]
    warned = [r for r in records if r.get("kind") == "preflight_warning"]
    assert [r.get("vehicle") for r in warned] == ["r1"] and "planned with 20 m" in warned[0]["text"], warned
    plan = next(r["plan"] for r in records if r.get("kind") == "plan")
    legs = [leg for stop in plan["stops"] for leg in stop["rovers"]]
    r1 = next(leg for leg in legs if leg["rover"] == "r1")
    length = sum(math.dist(p, q) for p, q in zip(r1["path"], r1["path"][1:], strict=False))
    assert length <= 20.0 + 1e-3, r1
