"""fleetctl against real ArduPilot firmware (SITL): an ArduRover carrier and ArduCopter rovers on one
ground-station port, stock parameters, flown through the command line as a user flies them.

Skipped with one line without ``FLEETCTL_ARDUPILOT_DIR`` (``.ci/run`` sets it when the firmware is
there). The firmware's own physics cannot carry a rover on the carrier: the rovers start where the
carrier starts, so deployment launches at the carrier's start and collection lands them at its stop
(on the deck in position, which is what fleetctl checks).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from ardupilot_team import TASKS, Team, ardupilot_team, horizontal, probe

pytestmark = pytest.mark.firmware

DECK = 1.5  # m: fleetctl's deck radius (fleetctl.run.state.DECK_RADIUS)
AT_TASK = 2.0  # m from the task, horizontally: a rover "at its task"
FIDELITY = 0.10  # flown within 10 % of planned


def assert_at_tasks(team: Team, assignment: dict[str, str]) -> None:
    seen = probe(team.fleet.gcs_port, 3.0)
    tasks = dict(TASKS)
    for task, rover in assignment.items():
        s = seen[11 + team.rovers.index(rover)]
        assert s.enu is not None and horizontal(s.enu, tasks[task]) < AT_TASK, (rover, task, s.enu)
        assert abs(s.enu[2] - tasks[task][2]) < 1.5, (rover, task, s.enu)


def test_status_deploy_collect_on_stock_ardupilot(tmp_path: Path) -> None:
    with ardupilot_team(tmp_path) as team:
        status = team.fleetctl("status")
        assert status.returncode == 0 and "all 4 vehicles connected and ready" in status.stdout, status.stdout

        proc, deploy = team.fly("deploy")
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:] + team.firmware_tail()
        assert deploy["result"] == "complete" and sorted(deploy["tasks_reached"]) == ["t1", "t2", "t3"]
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
        print(f"\nArduPilot deploy flown {deploy['makespan_flown']:.1f} s vs planned "
              f"{deploy['makespan_planned']:.1f} s; collect {collect['makespan_flown']:.1f} s vs "
              f"{collect['makespan_planned']:.1f} s")
