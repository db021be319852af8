"""fleetctl against real PX4 firmware (SITL with SIH physics): a rover carrier (airframe 10045) and
three quadcopters (10040) at the carrier's home, all on ``udpin://127.0.0.1:14550``, flown with the
command line as a user would (``--yes --headless --summary``) at PX4_SIM_SPEED_FACTOR 4
(``--speedup 4`` gives fleetctl the vehicles' clock).

Skipped in one line unless ``FLEETCTL_PX4_DIR`` names a PX4 build (``bin/px4``, ``etc/``).

The mission's rover speeds are PX4's (``Px4.speed_params``: MPC_XY_CRUISE 5 m/s, MPC_TKO_SPEED
1.5 m/s, MPC_LAND_SPEED 0.7 m/s); the take-off, touch-down and leg acceleration the plan uses are
PX4's measured handling (``Px4.handling_times``, ``Px4.planned_accel``). The faults (a rover's
firmware killed in flight, link loss after the controller is gone) fly a fleet of four
quadcopters first; then the tests run in file order on one fleet of three, on tasks drawn at random
(the seed printed; ``FLEETCTL_FW_SEED`` flies them again): status, deploy (the
rovers end at their tasks), collect (they land on the deck, the carrier is disarmed, status passes
again). A run killed with SIGKILL during its dwell and finished by ``resume`` flies a fleet of its
own before them (SIH cannot carry a rover: after a collection the rovers stand on the ground beside
the carrier, whose position drifts by most of a metre while it is parked, so a ``run`` on that
fleet finds a rover off the 1.5 m deck - docs/autopilots.md)."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from ardupilot_team import kill_run_once_deployed, probe
from px4_fleet import (
    GCS_PORT,
    ROOT,
    SKIP_REASON,
    TASKS,
    cli,
    mission_yaml,
    port_free,
    px4_fleet,
    random_task_positions,
    wait_ready,
)

from sitl.firmware import find_px4

pytestmark = pytest.mark.firmware

if find_px4() is None:
    pytest.skip(SKIP_REASON, allow_module_level=True)

SPEEDUP = 4
DECK_M = 1.5  # a rover "on the deck": this near the carrier, horizontally (fleetctl's deck radius)
# read after the run, up to ~30 s after the rover was loaded: the parked SIH carrier's position estimate
# drifts ~0.5 m/min (docs/autopilots.md) and the rover's own estimate does not move with it
NEAR_DECK_M = DECK_M + 0.5
TASK_M = 2.0  # a rover "at its task": this near it
LAND_MODE = (6 << 24) | (4 << 16)  # PX4 AUTO.LAND custom mode


@pytest.fixture(scope="module")
def px4(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    if not port_free():
        pytest.skip("UDP port 14550 (PX4's ground-station port) is in use")
    d = tmp_path_factory.mktemp("px4")
    seed = int(os.environ.get("FLEETCTL_FW_SEED", time.time_ns() % 100_000))
    print(f"\ntasks of seed {seed} (FLEETCTL_FW_SEED={seed} flies them again)")
    tasks = random_task_positions(seed)
    mission = d / "mission.yaml"
    mission.write_text(mission_yaml(tasks))
    with px4_fleet(speedup=SPEEDUP) as fleet:
        ctx: dict[str, Any] = {"fleet": fleet, "mission": mission, "dir": d,
                               "tasks": {f"t{i + 1}": p for i, p in enumerate(tasks)}}
        ctx["status"] = wait_ready(mission)
        yield ctx


def fly(px4: dict[str, Any], command: str, *extra: str) -> tuple[dict[str, Any], str]:
    summary = px4["dir"] / f"{command}.json"
    out = cli(command, "-m", str(px4["mission"]), "--yes", "--headless", "--speedup", str(SPEEDUP),
              "--summary", str(summary), "--runs", str(px4["dir"] / "runs"), *extra, timeout=120.0)
    assert summary.exists(), out.stdout[-2000:] + out.stderr[-2000:]
    return json.loads(summary.read_text()), out.stdout + out.stderr


def journal(summary: dict[str, Any]) -> list[dict[str, Any]]:
    return [json.loads(line) for line in Path(summary["journal"]).read_text().splitlines() if line.strip()]


def ratio(summary: dict[str, Any]) -> float:
    return float(summary["makespan_flown"]) / float(summary["makespan_planned"])


def test_a_killed_rover_is_replaced_and_link_loss_lands_the_rovers(tmp_path: Path) -> None:
    """Four quadcopters, three tasks, ``links.reassign_after: 2``, ``links.failsafe: land``: the
    first rover launched is killed in the air (its PX4 process, SIGKILL) and the spare on the deck
    flies its task (every task reached); once the controller is gone, NAV_DLL_ACT (land, set by the
    preflight) brings every rover down at its task."""
    if not port_free():
        pytest.skip("UDP port 14550 (PX4's ground-station port) is in use")
    mission = tmp_path / "mission.yaml"
    mission.write_text(mission_yaml(n_rovers=4, extra="links: {failsafe: land, reassign_after: 2}\n"))
    with px4_fleet(n_rovers=4, speedup=SPEEDUP) as fleet:
        wait_ready(mission)
        out = tmp_path / "deploy.json"
        env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")
        # direct: the spare takes off where the carrier stands (a replan of lee may move the carrier
        # to a better stop, away from the spare, which the firmware's physics cannot carry)
        argv = [sys.executable, "-m", "fleetctl.cli", "deploy", "-m", str(mission), "--speedup", str(SPEEDUP),
                "--planner", "direct", "--yes", "--headless", "--runs", str(tmp_path / "runs"),
                "--summary", str(out)]
        proc = subprocess.Popen(argv, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                text=True)
        killed, lines = None, []
        try:
            assert proc.stdout is not None
            for line in proc.stdout:
                lines.append(line)
                if killed is None and "rover_launched" in line:
                    killed = line.split("rover_launched", 1)[1].split(":", 1)[0].strip()
                    fleet.kill(killed)  # the rover's firmware dies in the air
            proc.wait(120)
        finally:
            if proc.poll() is None:
                proc.kill()
        text = "".join(lines)
        assert killed is not None, text[-3000:]
        s = json.loads(out.read_text())
        # the lost rover is reported, its task given back and planned again at once, and the spare
        # on the deck flies it (the deck check allows for the SIH carrier's drifting altitude)
        assert killed in s["rovers_lost"], s
        assert "task_returned" in text and "replan #1" in text, text[-3000:]
        assert sorted(s["tasks_reached"]) == ["t1", "t2", "t3"] and killed not in s["assignment"].values(), s
        assert "links.failsafe: land" in Path(s["journal"]).read_text()
        # the controller is gone: no ground-station heartbeat; COM_DL_LOSS_T (40 s: 10 s at 4x) later
        # the failsafe lands them
        seen = probe(GCS_PORT, 16.0, beat=False)
        tasks = {f"t{i + 1}": p for i, p in enumerate(TASKS)}
        for task, rid in s["assignment"].items():
            if rid in s["rovers_lost"]:
                continue  # its firmware is dead: nothing to hear (its task went back to the board)
            assert 11 + int(rid[1:]) - 1 in seen, (rid, sorted(seen), s)
            v = seen[11 + int(rid[1:]) - 1]
            assert v.custom_mode == LAND_MODE or v.landed_state == 1, (rid, v)  # AUTO.LAND or on the ground
            assert v.enu is not None and math.dist(v.enu[:2], tasks[task][:2]) < TASK_M, (rid, v.enu, task)



def test_a_run_killed_with_sigkill_is_finished_by_resume(tmp_path: Path) -> None:
    """``run`` killed (SIGKILL) while the rovers wait at their tasks; ``resume --run`` finishes it:
    every rover collected onto the deck, disarmed."""
    if not port_free():
        pytest.skip("UDP port 14550 (PX4's ground-station port) is in use")
    mission = tmp_path / "mission.yaml"
    mission.write_text(mission_yaml())
    with px4_fleet(speedup=SPEEDUP):
        wait_ready(mission)
        run_dir = tmp_path / "runs" / "killed"
        argv = [sys.executable, "-m", "fleetctl.cli", "run", "-m", str(mission), "--speedup", str(SPEEDUP),
                "--dwell", "20", "--yes", "--headless", "--run-dir", str(run_dir)]
        env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")
        kill_run_once_deployed(argv, env, ROOT)
        out = tmp_path / "resumed.json"
        resumed = cli("resume", "--run", str(run_dir), "--yes", "--headless", "--speedup", str(SPEEDUP),
                      "--summary", str(out), timeout=180.0)
        assert resumed.returncode == 0, resumed.stdout[-3000:] + resumed.stderr[-2000:]
        s = json.loads(out.read_text())
        assert s["result"] == "complete" and sorted(s["rovers_loaded"]) == ["r1", "r2", "r3"], s
        positions = where_landed({"mission": mission})
        for rid in ("r1", "r2", "r3"):  # on the ground next to the carrier, disarmed
            assert math.dist(positions[rid][:2], positions["carrier"][:2]) < NEAR_DECK_M, (rid, positions)


def test_status_sees_every_vehicle_ready(px4: dict[str, Any]) -> None:
    out = px4["status"]
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-2000:]
    assert "all 4 vehicles connected and ready" in out.stdout
    assert "route" not in out.stderr and "system 0" not in out.stderr  # no vehicle for sysid-0 messages


def test_deploy_reaches_every_task(px4: dict[str, Any]) -> None:
    s, log = fly(px4, "deploy")
    px4["deploy"] = s
    assert s["result"] == "complete", log[-3000:]
    assert sorted(s["tasks_reached"]) == ["t1", "t2", "t3"]
    assert s["link"]["route_conflicts"] == 0
    tasks = px4["tasks"]
    for rid, r in s["rovers_airborne"].items():  # each ends at its task (1 m acceptance radius)
        assert math.dist(r["position"], tasks[r["task"]]) < TASK_M, (rid, r)
    landed = [e for e in journal(s) if e["kind"] == "landed_state" and e.get("state") == "ON_GROUND"
              and e.get("vehicle") != "carrier"]
    assert not landed, f"a rover landed during the deployment: {landed}"
    print(f"deploy: flown {s['makespan_flown']:.1f} s vs planned {s['makespan_planned']:.1f} s "
          f"({ratio(s) - 1:+.0%})")


def test_collect_lands_every_rover_on_the_deck(px4: dict[str, Any]) -> None:
    if px4.get("deploy", {}).get("result") != "complete":
        pytest.skip("the deployment did not complete")
    s, log = fly(px4, "collect")
    assert s["result"] == "complete", log[-3000:]
    assert sorted(s["rovers_loaded"]) == ["r1", "r2", "r3"]
    assert s["link"]["route_conflicts"] == 0
    events = journal(s)
    deck = [e for e in events if e["kind"] == "stop_reached"][-1]["position"]
    positions = where_landed(px4)
    for rid in ("r1", "r2", "r3"):  # on the ground next to the carrier, nowhere else
        assert math.dist(positions[rid][:2], positions["carrier"][:2]) < NEAR_DECK_M, (rid, positions, deck)
    print(f"collect: flown {s['makespan_flown']:.1f} s vs planned {s['makespan_planned']:.1f} s "
          f"({ratio(s) - 1:+.0%})")
    parked = [e for e in events if e["kind"] == "carrier_parked"]
    assert parked and parked[-1]["disarmed"] is True, parked
    status = cli("status", "-m", str(px4["mission"]), "--timeout", "10")  # not refused as "already armed"
    assert status.returncode == 0, status.stdout[-2000:] + status.stderr[-1000:]


def where_landed(px4: dict[str, Any]) -> dict[str, tuple[float, float, float]]:
    """Every vehicle's position (mission frame), read with fleetctl's own link once disarmed."""
    import asyncio

    from fleetctl.mavlink.fleet import connect_fleet
    from fleetctl.mission import load_mission

    async def read() -> dict[str, tuple[float, float, float]]:
        mission = load_mission(px4["mission"])
        async with await connect_fleet(mission, timeout=10.0) as fleet:
            for v in fleet.rovers.values():
                await v.wait_until(lambda v: v.enu is not None and v.on_ground is True and not v.armed,
                                   20.0, "on the ground, disarmed")
            await fleet.carrier.wait_until(lambda v: v.enu is not None, 5.0, "a position")
            return {vid: v.enu for vid, v in fleet.vehicles.items() if v.enu is not None}

    return asyncio.run(read())

