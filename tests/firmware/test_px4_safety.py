"""Signing and geofence on real PX4 firmware (SITL with SIH physics), each on a fleet of its own: a
rover carrier (airframe 10045) and three quadcopters on ``udpin://127.0.0.1:14550``, flown with the
command line as a user would at PX4_SIM_SPEED_FACTOR 4.

Skipped in one line unless ``FLEETCTL_PX4_DIR`` names a PX4 build (``bin/px4``, ``etc/``)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from ardupilot_team import param_answered, probe, set_param
from px4_fleet import GCS_PORT, SKIP_REASON, TASKS, cli, mission_yaml, port_free, px4_fleet, wait_ready

from sitl.firmware import find_px4

pytestmark = pytest.mark.firmware

if find_px4() is None:
    pytest.skip(SKIP_REASON, allow_module_level=True)

SPEEDUP = 4
TASK_M = 2.0  # a rover "at its task": this near it, horizontally
LAND_MODE = (6 << 24) | (4 << 16)  # PX4 AUTO.LAND custom mode
ROVER_SYSIDS = (11, 12, 13)


def fly(mission: Path, tmp_path: Path, command: str, env: dict[str, str] | None = None) -> tuple[dict, str]:
    summary = tmp_path / f"{command}.json"
    out = cli(command, "-m", str(mission), "--yes", "--headless", "--speedup", str(SPEEDUP), "--summary",
              str(summary), "--runs", str(tmp_path / "runs"), timeout=120.0, env=env)
    assert summary.exists(), out.stdout[-2000:] + out.stderr[-2000:]
    return json.loads(summary.read_text()), out.stdout + out.stderr


def test_signing_is_provisioned_and_enforced(tmp_path: Path) -> None:
    """PX4 without a key: ``status`` says the vehicles are heard but unsigned; ``keys provision``
    gives each one the key (SETUP_SIGNING); then PX4 answers a request signed with the key and
    ignores one unsigned or signed with another key, and the deployment flies signed."""
    if not port_free():
        pytest.skip("UDP port 14550 (PX4's ground-station port) is in use")
    key = "5a" * 32
    mission = tmp_path / "mission.yaml"
    mission.write_text(mission_yaml(extra="links: {signing: {key_env: FLEETCTL_FW_KEY}}\n"))
    # a signing state of its own (the timestamps of earlier runs stay out of this test)
    env = {"FLEETCTL_FW_KEY": key, "XDG_STATE_HOME": str(tmp_path / "state")}
    with px4_fleet(speedup=SPEEDUP):
        status = wait_ready(mission, timeout=20.0, env=env)  # never ready: unsigned
        assert status.returncode != 0, status.stdout
        assert "heard, but unsigned" in status.stderr and "keys provision" in status.stderr, status.stderr
        prov = cli("keys", "provision", "--mission", str(mission), timeout=120.0, env=env)
        assert prov.returncode == 0, prov.stdout + prov.stderr
        ready = wait_ready(mission, env=env)
        assert ready.returncode == 0, ready.stdout[-2000:] + ready.stderr[-2000:]
        raw = bytes.fromhex(key)
        # each asks for a parameter of its own: a late answer to one is no answer to the next
        assert param_answered(GCS_PORT, 11, raw, "MAV_SYS_ID")  # signed: answered
        assert not param_answered(GCS_PORT, 11, None, "MAV_TYPE")  # unsigned: ignored by the firmware
        assert not param_answered(GCS_PORT, 11, bytes.fromhex("77" * 32), "MAV_COMP_ID")  # another key
        deploy, log = fly(mission, tmp_path, "deploy", env=env)
        assert deploy["result"] == "complete", log[-3000:]
        assert deploy["link"]["rejected_unsigned"] == 0, deploy


def test_geofence_is_uploaded_and_a_breach_makes_the_firmware_land(tmp_path: Path) -> None:
    """A polygon fence with a ceiling, uploaded to every vehicle (MISSION_TYPE_FENCE) with GF_ACTION
    land; once the rovers hover at their tasks, one rover's ceiling (GF_MAX_VER_DIST) is lowered below
    it: PX4 lands it where it is."""
    if not port_free():
        pytest.skip("UDP port 14550 (PX4's ground-station port) is in use")
    fence = "geofence: {polygon: [[-60, -60], [60, -60], [60, 60], [-60, 60]], alt_max: 15, action: land}\n"
    mission = tmp_path / "mission.yaml"
    mission.write_text(mission_yaml(extra=fence))
    with px4_fleet(speedup=SPEEDUP):
        ready = wait_ready(mission)
        assert ready.returncode == 0, ready.stdout[-2000:] + ready.stderr[-2000:]
        deploy, log = fly(mission, tmp_path, "deploy")
        assert deploy["result"] == "complete", log[-3000:]
        text = Path(deploy["journal"]).read_text()
        assert text.count("geofence uploaded (4 vertices") == 4, text[-2000:]
        rover = deploy["assignment"]["t1"]  # hovering 5 m above ground at t1
        sysid = ROVER_SYSIDS[int(rover[1:]) - 1]
        assert set_param(GCS_PORT, sysid, "GF_MAX_VER_DIST", 2.0) == 2.0
        seen = probe(GCS_PORT, 6.0, sysids=(sysid,))[sysid]
        # PX4 1.18: "Geofence: exceeding maximum altitude above Home", 5 s of hold (COM_FAIL_ACT_T),
        # then it lands and disarms
        assert any("geofence" in t.lower() for t in seen.texts), seen.texts
        assert seen.custom_mode == LAND_MODE or (seen.landed_state == 1 and seen.armed is False), seen
        assert seen.enu is not None and math.dist(seen.enu[:2], TASKS[0][:2]) < TASK_M, seen.enu
