"""Preflight (docs/field-safety.md): each check fails on its simulated fault and passes without, in
`fleetctl status` and before arming (a failing rover is left out, a failing carrier stops the run).
Real MAVLink over UDP against the simulated fleet."""

from __future__ import annotations

import asyncio
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from fleetctl.mavlink.fleet import connect_fleet
from fleetctl.run.flight import execute
from fleetctl.run.preflight import check_fleet, check_vehicle
from fleetctl.run.safety import gather
from tests.run.ctl_helpers import mission_dict, mission_from, sim_fleet, write_mission

ROOT = Path(__file__).resolve().parents[2]


def _by_check(row: object) -> dict[str, bool]:
    return {c.name: c.ok for c in row.checks}  # type: ignore[attr-defined]


async def test_every_check_fails_on_its_fault_and_passes_without(tmp_path: Path) -> None:
    faults = [
        {"vehicle": "r1", "kind": "no_gps"},
        {"vehicle": "r2", "kind": "unhealthy"},
        {"vehicle": "r3", "kind": "low_battery", "level": 0.05},
        {"vehicle": "r4", "kind": "low_battery", "level": 0.2},
    ]
    d = mission_dict(rovers=6, faults=faults)
    d["rovers"]["endurance_range"] = 200.0
    mission = mission_from(d, tmp_path)
    async with sim_fleet(d) as sim, await connect_fleet(mission, sim.endpoints, timeout=5.0) as fleet:
        await gather(fleet)
        await fleet.rovers["r5"].arm()
        await fleet.rovers["r5"].wait_until(lambda v: v.armed, 3.0, "armed")
        rows = check_fleet(fleet.vehicles, fleet.carrier_id, mission, command="deploy")
        fleet.rovers["r6"].home = None  # as if no HOME_POSITION came
        no_home = check_vehicle(fleet.rovers["r6"], mission, carrier=False, command="deploy")
    assert rows["carrier"].ok and rows["r6"].ok, (rows["carrier"].failures, rows["r6"].failures)
    assert all(_by_check(rows["r6"]).values()) and len(rows["r6"].checks) == 8
    assert _by_check(rows["r1"]) == {**_by_check(rows["r6"]), "gps": False}
    assert rows["r1"].failures == ["GPS no fix, 0 satellites: needs a 3D fix"]
    assert _by_check(rows["r2"]) == {**_by_check(rows["r6"]), "sensors": False}
    assert rows["r2"].failures == ["sensors not healthy: magnetometer"]
    assert rows["r3"].failures == ["battery 5 % is not above the reserve 10%"]
    # 20 %: above the 10 % reserve, but (0.2 - 0.1) x 200 m = 20 m < the deploy range 40 m: planned
    # with 20 m (the tasks are 4-5 m high: it reaches them from a stop under them)
    assert rows["r4"].ok and rows["r4"].range == pytest.approx(20.0)
    assert rows["r4"].check("battery").detail == (  # type: ignore[union-attr]
        "battery 20 % gives 20 m above the reserve, less than the deploy range 40 m (needs 30 %): "
        "planned with 20 m, flies only tasks it reaches")
    assert rows["r5"].failures == ["already armed"]
    assert no_home.failures == ["home position unknown (no HOME_POSITION received)"]
    # fleetctl resume takes over armed vehicles: that check is skipped
    assert "disarmed" not in _by_check(
        check_vehicle(fleet.rovers["r5"], mission, carrier=False, resuming=True)
    )


def test_status_fails_a_rover_without_gps_in_red(tmp_path: Path) -> None:
    d = mission_dict(rovers=2, speedup=10.0, faults=[{"vehicle": "r2", "kind": "no_gps"}])
    path = write_mission(d, tmp_path / "m.yaml")
    proc = subprocess.run(
        [sys.executable, "-m", "fleetctl.cli", "status", "--mission", str(path), "--timeout", "5"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=60,
        env=os.environ | {"PYTHONPATH": str(ROOT), "COLUMNS": "250"},
    )
    assert proc.returncode == 1, (proc.stdout, proc.stderr)
    assert "r2 (sysid 12) at " in proc.stderr and "GPS no fix, 0 satellites: needs a 3D fix" in proc.stderr
    assert "r1 (sysid" not in proc.stderr and "carrier (sysid" not in proc.stderr
    assert "no fix" in proc.stdout and "3D, 14 sat" in proc.stdout and "none (NAV_DLL_ACT 0)" in proc.stdout


async def test_the_runner_leaves_a_failing_rover_out_and_flies_the_spares(tmp_path: Path) -> None:
    d = mission_dict(
        rovers=4,
        faults=[
            {"vehicle": "r1", "kind": "unhealthy"},
            {"vehicle": "r3", "kind": "low_battery", "level": 0.05},
        ],
    )
    out = await asyncio.wait_for(
        execute(mission_from(d, tmp_path), "deploy", runs_dir=tmp_path / "runs"), 120
    )
    s = out.summary
    assert out.exit_code == 0, (out.error, s)
    assert sorted(s["tasks_reached"]) == ["t1", "t2"]
    assert set(s["assignment"].values()) == {"r2", "r4"}
    assert s["rovers_lost_reasons"]["r1"] == "failed preflight: sensors not healthy: magnetometer"
    assert s["rovers_lost_reasons"]["r3"].startswith("failed preflight: battery 5 %")
    records = [json.loads(line) for line in (out.run_dir / "journal.jsonl").read_text().splitlines()]
    failed = [r for r in records if r.get("kind") == "preflight_failed"]
    assert sorted(r.get("vehicle") for r in failed) == ["r1", "r3"]


async def test_a_failing_carrier_stops_the_run(tmp_path: Path) -> None:
    d = mission_dict(rovers=2, faults=[{"vehicle": "carrier", "kind": "no_gps"}])
    out = await asyncio.wait_for(execute(mission_from(d, tmp_path), "deploy", runs_dir=tmp_path / "runs"), 60)
    assert out.exit_code == 1 and out.error is not None
    assert out.error.startswith("the carrier carrier at udp://")
    assert "failed preflight: GPS no fix" in out.error and "fix it before flying" in out.error
    assert out.summary["tasks_reached"] == []


async def test_too_few_rovers_pass_preflight(tmp_path: Path) -> None:
    d = mission_dict(rovers=2, faults=[{"vehicle": "r2", "kind": "no_gps"}])
    out = await asyncio.wait_for(execute(mission_from(d, tmp_path), "deploy", runs_dir=tmp_path / "runs"), 60)
    assert out.exit_code == 1 and out.error is not None
    assert "only 1 rover(s) passed preflight for 2 tasks" in out.error and "r2 (failed preflight" in out.error


@pytest.mark.parametrize("require_all", [True])
async def test_require_all_refuses_a_rover_failing_preflight(tmp_path: Path, require_all: bool) -> None:
    d = mission_dict(rovers=3, faults=[{"vehicle": "r3", "kind": "no_gps"}])
    out = await asyncio.wait_for(
        execute(mission_from(d, tmp_path), "deploy", runs_dir=tmp_path / "runs", require_all=require_all), 60
    )
    assert out.exit_code == 1 and out.error is not None and "--require-all" in out.error and "r3" in out.error


async def test_a_sensor_flag_that_flickers_is_waited_out_and_one_that_stays_fails(tmp_path: Path) -> None:
    from fleetctl.mavlink.health import unhealthy_sensors
    from fleetctl.run.safety import SENSOR_SETTLE, settle_sensors
    from sitl.faults import Fault

    d = mission_dict(rovers=3)
    mission = mission_from(d, tmp_path)
    async with sim_fleet(d) as sim, await connect_fleet(mission, sim.endpoints, timeout=5.0) as fleet:
        await gather(fleet)
        speedup = d["sim"]["speedup"]
        # r1's magnetometer unhealthy for 1 wall s from now, r2's for good
        sim.faults.add(Fault("unhealthy", vehicle="r1", until=sim.sim_time + 1.0 * speedup))
        sim.faults.add(Fault("unhealthy", vehicle="r2"))
        for rid in ("r1", "r2"):
            await fleet.rovers[rid].wait_until(lambda v: bool(unhealthy_sensors(v)), 5.0, "unhealthy")
        rows = check_fleet(fleet.vehicles, fleet.carrier_id, mission, command="deploy")
        assert rows["r1"].failures == rows["r2"].failures == ["sensors not healthy: magnetometer"]
        assert rows["r3"].ok
        assert SENSOR_SETTLE > 1.0
        assert await settle_sensors(fleet.vehicles, rows)
        again = check_fleet(fleet.vehicles, fleet.carrier_id, mission, command="deploy")
        assert not await settle_sensors(fleet.vehicles, {"r3": rows["r3"]})  # nothing to wait for
    assert again["r1"].ok and again["r3"].ok
    assert again["r2"].failures == ["sensors not healthy: magnetometer"]


def test_docs_state_how_long_sensors_are_given_to_settle() -> None:
    from fleetctl.run.safety import SENSOR_SETTLE

    text = (ROOT / "docs" / "field-safety.md").read_text()
    assert f"given {SENSOR_SETTLE:g} s to report its sensors healthy" in text
