"""``fleetctl sim`` and the embedded simulated fleet with several carriers: every carrier and rover
served, each rover on its own carrier's deck and link (MAVLink heartbeats over real UDP)."""

from __future__ import annotations

import dataclasses
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from pymavlink import mavutil

from fleetctl.mission import load_mission
from fleetctl.mission.teams import several_teams
from fleetctl.run.context import ExecutionError
from fleetctl.run.sim import sim_fleet_config, sim_mission_dict
from sitl import FleetConfig
from tests.run.teams.teams_helpers import mission_from, two_teams, write_mission

ROOT = Path(__file__).resolve().parents[3]


def test_the_sim_config_holds_every_team(tmp_path: Path) -> None:
    cfg = sim_fleet_config(mission_from(two_teams(), tmp_path))
    assert [c.id for c in cfg.carriers] == ["c1", "c2"]
    assert {r.id: (r.sysid, r.carrier) for r in cfg.rovers} == {
        "r1": (11, "c1"),
        "r2": (12, "c1"),
        "r3": (31, "c2"),
        "r4": (32, "c2"),
    }
    assert cfg.carriers[1].position == (80.0, 0.0, 0.0)


def _heartbeats(url: str, sysids: set[int], timeout: float) -> set[int]:
    conn = mavutil.mavlink_connection(url.replace("udp://", "udpout:"), source_system=255)
    heard: set[int] = set()
    try:
        deadline = time.monotonic() + timeout
        while heard != sysids and time.monotonic() < deadline:
            mav = mavutil.mavlink
            conn.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            msg = conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
            if msg is not None and msg.get_srcSystem() in sysids:
                heard.add(msg.get_srcSystem())
    finally:
        conn.close()
    return heard


def test_fleetctl_sim_serves_every_carrier_and_rover(tmp_path: Path) -> None:
    path = write_mission(two_teams(), tmp_path / "two.yaml")
    cmd = [sys.executable, "-m", "fleetctl.cli", "sim", "--mission", str(path), "--speedup", "3"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        lines: list[str] = []
        deadline = time.monotonic() + 20
        assert proc.stdout is not None
        while len([ln for ln in lines if "udp://" in ln]) < 6 and time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line)
        text = "".join(lines)
        rows = re.finditer(r"^\s+(\S+)\s+sysid (\d+)\s+(udp://\S+)$", text, re.M)
        found = {m.group(1): (int(m.group(2)), m.group(3)) for m in rows}
        assert set(found) == {"c1", "c2", "r1", "r2", "r3", "r4"}, text
        assert found["r1"][1] == found["r2"][1] == found["c1"][1]  # a team shares its carrier's link
        assert found["r3"][1] == found["r4"][1] == found["c2"][1] != found["c1"][1]
        for team in ("c1", "c2"):
            url = found[team][1]
            want = {sysid for sysid, u in found.values() if u == url}
            assert _heartbeats(url, want, 10.0) == want
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, err


def test_one_team_missions_get_the_simulated_fleet_they_had() -> None:
    # the typed configuration (every team) is the one the mission-dict reading gave one team
    compared = 0
    for path in sorted((ROOT / "missions").glob("**/*.yaml")):
        m = load_mission(path)
        if several_teams(m):
            with pytest.raises(ExecutionError, match="sim_fleet_config"):
                sim_mission_dict(m)
            continue
        for command in ("deploy", "collect"):
            try:
                old = FleetConfig.from_mission_dict(sim_mission_dict(m, command))
            except ExecutionError:  # collect without a collection: section
                with pytest.raises(ExecutionError):
                    sim_fleet_config(m, command)
                continue
            # None meant "max_speed" (climb) and "the climb rate" (land) there; spelled out here
            old.rovers = [
                dataclasses.replace(
                    r,
                    climb_rate=r.climb_rate or r.max_speed,
                    land_speed=r.land_speed or r.climb_rate or r.max_speed,
                )
                for r in old.rovers
            ]
            assert sim_fleet_config(m, command) == old, (path, command)
            compared += 1
    assert compared >= 10
