"""A long operation on real ArduPilot firmware: a small one (2 ArduCopter rovers on an ArduRover
carrier's ``sitl.json_physics`` deck, 4 tasks worked hovering for short durations, battery swaps on
the deck) flown with ``fleetctl run`` as a user flies it. The firmware times each task's work
(NAV_LOITER_TIME). Skipped with one line without ``FLEETCTL_ARDUPILOT_DIR``.

Work on the ground: ArduCopter disarms under a sortie's NAV_LAND (0.8 s after its "Land") and
restarts its mission at item 1, so a NAV_DELAY after it never runs; the controller ends the
sortie's mission at the landing, times the work and starts the rest (docs/autopilots.md)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from ardupilot_team import journal, mission_yaml
from deck_team import DECK, GCS_PORT, deck_team

pytestmark = pytest.mark.firmware

TASKS = (("o1", (20.0, 10.0, 5.0)), ("o2", (25.0, -10.0, 5.0)), ("o3", (10.0, 30.0, 5.0)),
         ("o4", (-15.0, 25.0, 5.0)))
DURATIONS = {"o1": 10.0, "o2": 15.0, "o3": 10.0, "o4": 15.0}


def operation_mission(ground: tuple[str, ...] = ()) -> dict[str, Any]:
    m = mission_yaml(GCS_PORT, 2, tasks=TASKS, extra={
        "operation": True,
        "carrier": {"max_speed": 3.0, "accel": 1.0, "swap_time": 5.0, "deck_height": DECK.height},
        # a battery for a sortie or two: the planner may swap one on the deck
        "rovers": {"deploy_range": 60.0, "endurance_range": 300.0},
    })
    for t in m["tasks"]:
        t["duration"] = DURATIONS[t["id"]]
        if t["id"] in ground:
            t["work"] = "ground"
            t["position"][2] = 0.0
    return m


Rows = list[dict[str, Any]]


def fly_operation(tmp_path: Path, ground: tuple[str, ...] = ()) -> tuple[dict[str, Any], Rows]:
    """The operation flown with ``fleetctl run`` on the deck: complete, every task done once, every
    rover back; its summary and journal."""
    with deck_team(tmp_path, n_rovers=2, mission=operation_mission(ground=ground)) as (team, _world):
        proc, run = team.fly("run", timeout=360)  # ~45 s wall when it flies; a hang fails in 6 min
        assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:] + team.firmware_tail()
        assert run["result"] == "complete", run
        assert sorted(run["tasks_done"]) == sorted(DURATIONS), run
        assert sorted(run["rovers_loaded"]) == team.rovers, run
        rows = journal(Path(run["journal"]).parent)
    assert sorted(r["task"] for r in rows if r.get("kind") == "task_done") == sorted(DURATIONS)
    return run, rows


def test_a_small_operation_flies_on_ardupilot(tmp_path: Path) -> None:
    run, rows = fly_operation(tmp_path)
    done = [r for r in rows if r.get("kind") == "task_done"]
    swaps = [r for r in rows if r.get("kind") == "battery_swapped"]
    print(f"\nArduPilot operation: flown {run['makespan_flown']:.1f} s vs planned "
          f"{run['makespan_planned']:.1f} s; swaps {len(swaps)}; worked "
          f"{ {r['task']: r.get('worked') for r in done} }")


def test_work_on_the_ground_flies_on_ardupilot(tmp_path: Path) -> None:
    ground = ("o2", "o4")
    run, rows = fly_operation(tmp_path, ground)
    done = {r["task"]: r for r in rows if r.get("kind") == "task_done"}
    for t in ground:  # timed by the controller from the touch-down: at least its duration
        assert done[t]["worked"] >= DURATIONS[t], done[t]
    continued = [r for r in rows if r.get("kind") == "sortie_continued"]
    print(f"\nArduPilot operation with work on the ground: flown {run['makespan_flown']:.1f} s vs "
          f"planned {run['makespan_planned']:.1f} s; sorties continued {len(continued)}; worked "
          f"{ {t: r.get('worked') for t, r in done.items()} }")
