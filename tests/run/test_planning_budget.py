"""A run's first plan of a phase gets the mission's planner.budget_ms; its replans at most
REPLAN_BUDGET_MS (fleetctl.run.planning), so that the fleet does not wait on a long search."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

import planners
from fleetctl.mission import load_mission
from fleetctl.run.planning import REPLAN_BUDGET_MS, Planning

RECON = Path(__file__).resolve().parents[2] / "missions" / "recon.yaml"


async def test_replans_get_the_small_budget(monkeypatch: pytest.MonkeyPatch) -> None:
    mission = load_mission(RECON)
    mission = dataclasses.replace(mission, planner=dataclasses.replace(mission.planner, budget_ms=400.0))
    seen: list[float | None] = []
    lee = planners.DEPLOY_PLANNERS["lee"]

    def spy(problem: Any) -> Any:
        seen.append(problem.budget_ms)
        return lee(dataclasses.replace(problem, budget_ms=None))  # the quick plan: the test stays fast

    monkeypatch.setitem(planners.DEPLOY_PLANNERS, "lee", spy)

    async def commit(*args: Any, **kwargs: Any) -> None:
        return None

    state = SimpleNamespace(set_plan=lambda doc: None, event=lambda *a, **k: None)
    ctx = SimpleNamespace(mission=dataclasses.replace(mission, geofence=None), commit=commit, state=state)
    planning = Planning(ctx, "lee")  # type: ignore[arg-type]
    problem = mission.deploy_problem()
    assert problem.budget_ms == 400.0
    await planning.plan("deploy", problem)
    await planning.plan("deploy", problem)
    assert seen == [400.0, REPLAN_BUDGET_MS]
