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
from fleetctl.run.budget import BUDGET_ENV, DEFAULT_BUDGET_MS, offline_budget, replan_budget
from fleetctl.run.planning import REPLAN_BUDGET_MS, Planning

RECON = Path(__file__).resolve().parents[2] / "missions" / "recon.yaml"


async def _budgets_seen(monkeypatch: pytest.MonkeyPatch, named: float | None) -> list[float | None]:
    """The budgets the planner is given for a first plan and a replan of a mission naming ``named``."""
    mission = load_mission(RECON)
    mission = dataclasses.replace(mission, planner=dataclasses.replace(mission.planner, budget_ms=named))
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
    assert problem.budget_ms == named
    await planning.plan("deploy", problem)
    await planning.plan("deploy", problem)
    return seen


async def test_replans_get_the_small_budget(monkeypatch: pytest.MonkeyPatch) -> None:
    assert await _budgets_seen(monkeypatch, 400.0) == [400.0, REPLAN_BUDGET_MS]


async def test_a_first_plan_searches_by_default_replans_are_quick(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(BUDGET_ENV, raising=False)  # (the suite's conftest asks for quick plans)
    assert await _budgets_seen(monkeypatch, None) == [DEFAULT_BUDGET_MS, None]


async def test_the_environment_or_zero_asks_for_the_quick_plan(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(BUDGET_ENV, "0")
    assert await _budgets_seen(monkeypatch, None) == [None, None]
    monkeypatch.setenv(BUDGET_ENV, "250")
    assert await _budgets_seen(monkeypatch, None) == [250.0, None]
    assert await _budgets_seen(monkeypatch, 0.0) == [None, None]


async def test_a_collections_first_plan_searches_only_for_a_named_budget(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Its rovers hover while it plans: no default search, the mission's budget when it names one."""
    monkeypatch.delenv(BUDGET_ENV, raising=False)
    seen: list[float | None] = []
    lee = planners.COLLECT_PLANNERS["lee"]

    def spy(problem: Any) -> Any:
        seen.append(problem.budget_ms)
        return lee(dataclasses.replace(problem, budget_ms=None))

    monkeypatch.setitem(planners.COLLECT_PLANNERS, "lee", spy)

    async def commit(*args: Any, **kwargs: Any) -> None:
        return None

    for named in (None, 300.0):
        mission = load_mission(RECON)
        mission = dataclasses.replace(mission, planner=dataclasses.replace(mission.planner, budget_ms=named))
        state = SimpleNamespace(set_plan=lambda doc: None, event=lambda *a, **k: None)
        ctx = SimpleNamespace(mission=dataclasses.replace(mission, geofence=None), commit=commit, state=state)
        problem = mission.collect_problem()
        await Planning(ctx, "lee").plan("collect", problem)  # type: ignore[arg-type]
    assert seen == [None, 300.0]


def test_budget_rules(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(BUDGET_ENV, raising=False)
    assert offline_budget(None) == DEFAULT_BUDGET_MS and offline_budget(0.0) is None
    assert offline_budget(120.0) == 120.0
    assert replan_budget(None) is None and replan_budget(0.0) is None
    assert replan_budget(10.0) == 10.0 and replan_budget(5000.0) == REPLAN_BUDGET_MS
    monkeypatch.setenv(BUDGET_ENV, "soon")
    with pytest.raises(ValueError, match=BUDGET_ENV):
        offline_budget(None)
