"""fleetctl against real ArduPilot firmware (SITL): an ArduRover carrier and ArduCopter rovers on one
ground-station port, stock parameters, flown through the command line as a user flies them.

Skipped with one line without ``FLEETCTL_ARDUPILOT_DIR`` (``.ci/run`` sets it when the firmware is
there). The firmware's own physics cannot carry a rover on the carrier: the rovers start where the
carrier starts, so deployment launches at the carrier's start and collection lands them at its stop
(on the deck in position, which is what fleetctl checks).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from ardupilot_team import (
    Team,
    ardupilot_team,
    horizontal,
    kill_run_once_deployed,
    mission_yaml,
    param_answered,
    probe,
    random_tasks,
    run_dir_of,
    set_param,
)
from pymavlink.dialects.v20 import ardupilotmega as M

pytestmark = pytest.mark.firmware

DECK = 1.5  # m: fleetctl's deck radius (fleetctl.run.state.DECK_RADIUS)
AT_TASK = 2.0  # m from the task, horizontally: a rover "at its task"
LAND_MODE = 9  # ArduCopter LAND


def assert_at_tasks(team: Team, assignment: dict[str, str]) -> None:
    seen = probe(team.fleet.gcs_port, 3.0)
    tasks = team.tasks
    for task, rover in assignment.items():
        s = seen[11 + team.rovers.index(rover)]
        assert s.enu is not None and horizontal(s.enu, tasks[task]) < AT_TASK, (rover, task, s.enu)
        assert abs(s.enu[2] - tasks[task][2]) < 1.5, (rover, task, s.enu)


def test_status_deploy_collect_on_stock_ardupilot(tmp_path: Path) -> None:
    seed = int(os.environ.get("FLEETCTL_FW_SEED", time.time_ns() % 100_000))
    print(f"\ntasks of seed {seed} (FLEETCTL_FW_SEED={seed} flies them again)")
    tasks = random_tasks(seed)
    with ardupilot_team(tmp_path, mission=mission_yaml(14560, 3, tasks=tasks)) as team:
        status = team.fleetctl("status")
        assert status.returncode == 0 and "all 4 vehicles connected and ready" in status.stdout, status.stdout

        proc, deploy = team.fly("deploy")
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:] + team.firmware_tail()
        assert deploy["result"] == "complete" and sorted(deploy["tasks_reached"]) == ["t1", "t2", "t3"], tasks
        assert_at_tasks(team, deploy["assignment"])

        proc, collect = team.fly("collect")
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:] + team.firmware_tail()
        assert sorted(collect["rovers_loaded"]) == team.rovers
        seen = probe(team.fleet.gcs_port, 4.0)
        carrier = seen[1].enu
        assert carrier is not None
        for k, rid in enumerate(team.rovers):  # down on the deck (where the carrier stands) and disarmed
            s = seen[11 + k]
            assert s.enu is not None and horizontal(s.enu, carrier) < DECK, (rid, s.enu, carrier)
            assert s.armed is False, rid
        # the carrier is parked after a complete collection: the team is ready for the next run
        again = team.fleetctl("status")
        assert again.returncode == 0, again.stdout[-2000:] + again.stderr[-1500:]
        proc, run = team.fly("run", "--dwell", "5")
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:] + team.firmware_tail()
        assert sorted(run["tasks_reached"]) == ["t1", "t2", "t3"], run
        assert sorted(run["rovers_loaded"]) == team.rovers, run
        print(f"\nArduPilot deploy flown {deploy['makespan_flown']:.1f} s vs planned "
              f"{deploy['makespan_planned']:.1f} s; collect {collect['makespan_flown']:.1f} s vs "
              f"{collect['makespan_planned']:.1f} s; run {run['makespan_flown']:.1f} s vs "
              f"{run['makespan_planned']:.1f} s")


def test_link_loss_failsafe_is_set_and_lands_the_rovers_at_their_tasks(tmp_path: Path) -> None:
    extra = {"links": {"failsafe": "land"}}
    with ardupilot_team(tmp_path, gcs_port=14561, instance_base=10,
                        mission=mission_yaml(14561, 3, extra=extra)) as team:
        proc, deploy = team.fly("deploy")
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:] + team.firmware_tail()
        journal_text = (run_dir_of(proc) / "journal.jsonl").read_text()
        assert "links.failsafe: land" in journal_text
        # the controller is gone: no ground-station heartbeat. FS_GCS_TIMEOUT later the copters land
        seen = probe(team.fleet.gcs_port, 12.0, beat=False)
        tasks = team.tasks
        for task, rover in deploy["assignment"].items():
            s = seen[11 + team.rovers.index(rover)]
            assert s.custom_mode == LAND_MODE or s.landed_state == M.MAV_LANDED_STATE_ON_GROUND, (rover, s)
            assert s.enu is not None and horizontal(s.enu, tasks[task]) < AT_TASK, (rover, s.enu)
            assert any("failsafe" in t.lower() for t in s.texts) or s.custom_mode == LAND_MODE, s.texts


def test_a_rover_killed_in_flight_is_replaced_by_a_spare(tmp_path: Path) -> None:
    extra = {"links": {"reassign_after": 2.0}}
    with ardupilot_team(tmp_path, n_rovers=4, gcs_port=14562, instance_base=40,
                        mission=mission_yaml(14562, 4, extra=extra)) as team:
        out = tmp_path / "deploy.json"
        argv = [sys.executable, "-m", "fleetctl.cli", "deploy", "--mission", str(team.mission),
                "--speedup", "4", "--yes", "--headless", "--runs", str(team.runs), "--summary", str(out)]
        proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        try:
            assert proc.stdout is not None
            killed = None
            lines = []
            for line in proc.stdout:
                lines.append(line)
                if killed is None and "rover_launched" in line:
                    killed = line.split("rover_launched", 1)[1].split(":", 1)[0].strip()
                    team.fleet.kill(killed)  # the rover's firmware dies in the air
            proc.wait(240)
        finally:
            if proc.poll() is None:
                proc.kill()
        text = "".join(lines)
        assert killed is not None, text
        summary = json.loads(out.read_text())
        assert summary["result"] == "complete", text[-3000:]
        assert killed in summary["rovers_lost"] and killed not in summary["assignment"].values(), summary
        assert sorted(summary["tasks_reached"]) == ["t1", "t2", "t3"]
        assert "r4" in summary["assignment"].values(), summary  # the spare flew the lost rover's task
        assert_at_tasks(team, summary["assignment"])


def test_run_killed_with_sigkill_is_finished_by_resume(tmp_path: Path) -> None:
    with ardupilot_team(tmp_path, gcs_port=14563, instance_base=50, mission=mission_yaml(14563, 3)) as team:
        run_dir = tmp_path / "runs" / "killed"
        argv = [sys.executable, "-m", "fleetctl.cli", "run", "--mission", str(team.mission), "--speedup", "4",
                "--dwell", "20", "--yes", "--headless", "--run-dir", str(run_dir)]
        kill_run_once_deployed(argv)
        out = tmp_path / "resumed.json"
        resumed = team.fleetctl("resume", "--run", str(run_dir), "--yes", "--headless", "--speedup", "4",
                                "--summary", str(out), timeout=300)
        assert resumed.returncode == 0, resumed.stdout[-3000:] + resumed.stderr[-2000:] + team.firmware_tail()
        summary = json.loads(out.read_text())
        assert summary["result"] == "complete" and sorted(summary["rovers_loaded"]) == team.rovers, summary
        seen = probe(team.fleet.gcs_port, 4.0)
        carrier = seen[1].enu
        assert carrier is not None
        for k, rid in enumerate(team.rovers):
            s = seen[11 + k]
            assert s.enu is not None and horizontal(s.enu, carrier) < DECK and s.armed is False, (rid, s.enu)


def test_signing_is_provisioned_and_enforced(tmp_path: Path) -> None:
    key = "5a" * 32
    extra = {"links": {"signing": {"key_env": "FLEETCTL_FW_KEY"}}}
    # SERIAL1, a telemetry radio's port: ArduPilot takes unsigned messages on SERIAL0 (USB) always
    with ardupilot_team(tmp_path, gcs_port=14564, instance_base=56, n_rovers=3, gcs_serial=1,
                        mission=mission_yaml(14564, 3, extra=extra),
                        # a signing state of its own: timestamps that earlier runs reserved ahead of
                        # the clock would put this test's probe more than 60 s behind the firmware
                        env={"FLEETCTL_FW_KEY": key, "XDG_STATE_HOME": str(tmp_path / "state")},
                        ready=False) as team:
        # not provisioned yet: heartbeats arrive unsigned, and status says so
        deadline = time.monotonic() + 90
        while True:
            status = team.fleetctl("status", "--timeout", "3", timeout=60)
            if "heard, but unsigned" in status.stderr or time.monotonic() > deadline:
                break
        assert "heard, but unsigned" in status.stderr and "keys provision" in status.stderr, status.stderr
        prov = team.fleetctl("keys", "provision", "--mission", str(team.mission), timeout=120)
        assert prov.returncode == 0, prov.stdout + prov.stderr
        team.wait_ready()
        port, raw = team.fleet.gcs_port, bytes.fromhex(key)
        # each asks for a parameter of its own: a late answer to one is no answer to the next
        assert param_answered(port, 11, raw, "SYSID_THISMAV")  # signed: answered
        assert not param_answered(port, 11, None, "FRAME_CLASS")  # unsigned: ignored by the firmware
        assert not param_answered(port, 11, bytes.fromhex("77" * 32), "FRAME_TYPE")  # another key: ignored
        proc, deploy = team.fly("deploy")
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:] + team.firmware_tail()
        assert deploy["result"] == "complete" and deploy["link"]["rejected_unsigned"] == 0, deploy


def test_geofence_is_uploaded_and_a_breach_makes_the_firmware_land(tmp_path: Path) -> None:
    fence = {"polygon": [[-60, -60], [60, -60], [60, 60], [-60, 60]], "alt_max": 15, "action": "land"}
    with ardupilot_team(tmp_path, gcs_port=14565, instance_base=70, n_rovers=3,
                        mission=mission_yaml(14565, 3, extra={"geofence": fence})) as team:
        proc, deploy = team.fly("deploy")
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:] + team.firmware_tail()
        text = (run_dir_of(proc) / "journal.jsonl").read_text()
        assert text.count("geofence uploaded (4 vertices") == 4, text[-2000:]
        # the fence's ceiling drops below the hovering rovers (t1 at 6 m): a breach, the firmware lands
        rover = deploy["assignment"]["t1"]
        sysid = 11 + team.rovers.index(rover)
        assert set_param(team.fleet.gcs_port, sysid, "FENCE_ALT_MAX", 3.0) == 3.0
        seen = probe(team.fleet.gcs_port, 6.0)[sysid]
        # LAND on a copter hovering in AUTO: the breach's action (its "Fence Breach" STATUSTEXT may come
        # before the probe listens: once in CI only the touch-down's texts were heard)
        assert seen.custom_mode == LAND_MODE, seen
        assert seen.enu is not None and horizontal(seen.enu, team.tasks["t1"]) < AT_TASK  # lands where it is
