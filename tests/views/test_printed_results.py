"""What the commands print of their results: the line a flying command ends with (and one per
team), from the run summary (fleetctl.views.outcome); the table of ``fleetctl plan``
(fleetctl.views.plan_summary)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

import planners
from fleetctl.mission import load_mission
from fleetctl.run.lifecycle import RunOutcome
from fleetctl.views.outcome import outcome_lines, team_line
from fleetctl.views.plan_summary import gap_percent, print_plan_summary, stop_rows

ROOT = Path(__file__).resolve().parents[2]
RECON = ROOT / "missions" / "recon.yaml"


def test_a_complete_deployment_names_tasks_makespans_and_the_records() -> None:
    mission = load_mission(RECON)
    summary = {"result": "complete", "tasks_reached": ["t1", "t2"], "tasks_unserved": ["t3"],
               "makespan_flown": 41.26, "makespan_planned": 40.91}
    lines = outcome_lines("deploy", mission, RunOutcome(0, summary, Path("runs/x")))
    assert lines == ["deploy complete: 2/3 tasks reached, makespan 41.3 s (planned 40.9 s); "
                     "records in runs/x"]


def test_a_collection_counts_rovers_and_airborne_ones() -> None:
    mission = load_mission(RECON)
    summary = {"result": "incomplete", "rovers_loaded": ["r1"], "rovers_airborne": {"r2": {}, "r3": {}}}
    lines = outcome_lines("collect", mission, RunOutcome(1, summary, Path("d")))
    assert lines == ["collect incomplete: 1 rovers loaded, 2 rovers airborne; records in d"]


def test_without_unserved_tasks_the_mission_gives_the_count() -> None:
    mission = load_mission(RECON)
    summary = {"result": "incomplete", "tasks_reached": []}
    line = outcome_lines("run", mission, RunOutcome(1, summary, None))[0]
    assert line == f"run incomplete: 0/{len(mission.tasks)} tasks reached; records in None"


def test_a_line_per_team() -> None:
    mission = load_mission(RECON)
    c1 = {"carrier": "c1", "deploy": {"tasks_reached": ["t1", "t2"], "tasks_planned": ["t1"],
                                      "tasks_received": ["t2"], "makespan_flown": 20.0,
                                      "makespan_planned": 19.5},
          "collect": {"rovers_loaded": ["r1"], "rovers_planned": ["r1", "r2"]}}
    c2 = {"carrier": "c2", "lost": True, "deploy": {"tasks_reached": [], "tasks_planned": ["t3"],
                                                    "tasks_received": []}}
    summary = {"result": "incomplete", "tasks_reached": ["t1", "t2"], "tasks_unserved": ["t3"],
               "teams": [c1, c2]}
    lines = outcome_lines("run", mission, RunOutcome(1, summary, Path("d")))
    assert lines[1:] == ["  team c1; deploy: 2/2 tasks reached (1 handed to it) in 20.0 s (planned 19.5 s); "
                         "collect: 1/2 rovers loaded",
                         "  team c2 (carrier lost); deploy: 0/1 tasks reached"]
    assert team_line({"carrier": "c3"}) == "team c3"


def test_the_plan_table_has_a_row_per_stop_with_every_rover() -> None:
    mission = load_mission(RECON)
    problem = dataclasses.replace(mission.deploy_problem(), budget_ms=0.0)
    plan = planners.DEPLOY_PLANNERS["lee"](problem)
    rows = stop_rows(plan)
    assert [r[0] for r in rows] == [str(k) for k in range(1, len(plan.stops) + 1)]
    legs = [leg for stop in plan.stops for leg in stop.rovers]
    assert sum(r[4].count("→") for r in rows) == len(legs) == len(mission.tasks)
    for row, stop in zip(rows, plan.stops, strict=True):
        assert float(row[5]) == pytest.approx(max(leg.arrive for leg in stop.rovers), abs=0.005)


def test_the_gap_to_the_lower_bound() -> None:
    assert gap_percent(50.0, 40.0) == pytest.approx(20.0)
    assert gap_percent(0.0, 0.0) == 0.0


def test_the_summary_prints_makespan_and_bound(capsys: pytest.CaptureFixture[str]) -> None:
    mission = load_mission(RECON)
    plan = planners.DEPLOY_PLANNERS["lee"](dataclasses.replace(mission.deploy_problem(), budget_ms=0.0))
    print_plan_summary(mission, plan, plan.makespan / 2)
    out = capsys.readouterr().out
    assert f"makespan        {plan.makespan:.2f} s" in out
    assert "(plan is within 50.0 % of it)" in out
