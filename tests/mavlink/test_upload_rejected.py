"""A rejected mission upload. The simulated fleet's ``reject_mission`` fault makes a
vehicle refuse every upload like a real autopilot whose feasibility check fails: a STATUSTEXT with
its reason, then MISSION_ACK MAV_MISSION_DENIED. The link raises with the result name, the vehicle
proxy attaches the autopilot's reason, and ``fleetctl deploy`` exits non-zero naming the vehicle
and the reason, without a traceback."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.mavlink.fleet import connect_fleet
from fleetctl.mavlink.link import Link, MissionRejected
from fleetctl.mission import load_mission
from sitl import Fault
from sitl.vehicle import MISSION_REJECTED_TEXT
from tests.mavlink.test_link import waypoints
from tests.run.ctl_helpers import mission_dict, mission_from, sim_fleet, write_mission

ROOT = Path(__file__).resolve().parents[2]


async def test_link_upload_to_a_refusing_vehicle_raises_with_the_result_name(tmp_path: Path) -> None:
    async with sim_fleet(mission_dict()) as sim:
        async with Link(sim.endpoints["carrier"]) as link:
            await link.expect("HEARTBEAT", sysid=11)
            await link.upload_mission(11, waypoints(3))  # accepted before the fault
            sim.inject(Fault("reject_mission", vehicle="r1"))
            with pytest.raises(MissionRejected, match="MAV_MISSION_DENIED") as exc:
                await link.upload_mission(11, waypoints(5))
            assert exc.value.result == M.MAV_MISSION_DENIED and exc.value.sysid == 11
            await link.upload_mission(12, waypoints(2))  # the other rover still accepts
            back = await link.download_mission(11)
        assert len(back) == 3  # the refusing vehicle kept its old mission
        assert any(MISSION_REJECTED_TEXT in text for _t, _sev, text in sim.vehicle("r1").statustexts)


async def test_vehicle_proxy_reports_the_autopilots_reason(tmp_path: Path) -> None:
    d = mission_dict(faults=[{"vehicle": "carrier", "kind": "reject_mission"}])
    mission = mission_from(d, tmp_path)
    assert [f.kind for f in mission.sim.faults] == ["reject_mission"]
    async with sim_fleet(d) as sim, await connect_fleet(mission, sim.endpoints, timeout=5.0) as fleet:
        with pytest.raises(MissionRejected, match="MAV_MISSION_DENIED") as exc:
            await fleet.carrier.upload_mission(waypoints(2))
        assert exc.value.reason == MISSION_REJECTED_TEXT
        await fleet.rovers["r1"].upload_mission(waypoints(2))  # only the carrier refuses


def test_mission_file_rejects_parameters_on_a_reject_mission_fault(tmp_path: Path) -> None:
    from fleetctl.mission import MissionError

    d = mission_dict(faults=[{"vehicle": "carrier", "kind": "reject_mission", "rate": 0.5}])
    with pytest.raises(MissionError, match="rate"):
        load_mission(write_mission(d, tmp_path / "m.yaml"))


def test_cli_deploy_whose_carrier_rejects_its_mission_exits_nonzero_with_the_reason(tmp_path: Path) -> None:
    d = mission_dict(faults=[{"vehicle": "carrier", "kind": "reject_mission"}])
    path = write_mission(d, tmp_path / "reject.yaml")
    out = tmp_path / "s.json"
    proc = subprocess.run(
        [sys.executable, "-m", "fleetctl.cli", "deploy", "--headless", "--speedup", "20",
         "--mission", str(path), "--summary", str(out)],
        cwd=tmp_path, capture_output=True, text=True, timeout=60,
        env=os.environ | {"PYTHONPATH": str(ROOT)})  # this checkout, whatever fleetctl is installed
    err = proc.stderr
    assert proc.returncode != 0, (proc.stdout[-2000:], err[-2000:])
    assert "Traceback" not in err and "Traceback" not in proc.stdout
    line = next((x for x in err.splitlines() if x.startswith("fleetctl: error:")), "")
    assert "carrier" in line and "MAV_MISSION_DENIED" in line and MISSION_REJECTED_TEXT in line, err
    s = json.loads(out.read_text())
    assert s["result"] == "incomplete" and MISSION_REJECTED_TEXT in s["error"]
    assert s["tasks_reached"] == [] and sorted(s["tasks_unserved"]) == ["t1", "t2"]
