"""Planning inside a run: the planner a phase uses, the plan record (write-ahead) and the
compilation of a plan into mission items for the live fleet."""

from __future__ import annotations

import asyncio
import dataclasses
from collections.abc import Callable
from typing import Any

import planners
from fleetctl.mavlink.compile import CompiledPlan, CompileError, compile_for_fleet
from fleetctl.mission.flight import MEET_HEIGHT
from fleetctl.run.budget import REPLAN_BUDGET_MS, offline_budget, replan_budget
from fleetctl.run.context import ExecutionError, RunContext
from fleetctl.run.kinds import Ev
from fleetctl.run.safety import check_plan
from planners.core.plan import Plan
from planners.core.problem import PlanningError

COLLECT_MEET_HEIGHT = MEET_HEIGHT  # m above the carrier's stop where a returning rover waits for the carrier
class Planning:
    """Plans a phase with the mission's planner (or the command line's ``planner``: ``NAME`` for
    both phases or ``DEPLOY,COLLECT``); every plan is journalled before it flies."""

    def __init__(
        self,
        ctx: RunContext,
        planner: str | None = None,
        write_plan: Callable[[str, Plan], None] | None = None,
    ) -> None:
        self.ctx = ctx
        self.planner = planner
        self.write_plan = write_plan
        self.planned: set[str] = set()  # the kinds planned once already: later plans are replans

    def name(self, kind: str) -> str:
        given = None
        if self.planner:
            parts = [p.strip() for p in self.planner.split(",")]
            given = parts[0] if kind == "deploy" else parts[-1]
        return given or self.ctx.mission.planner_for(kind)

    async def plan(self, kind: str, problem: Any) -> Plan:
        registry = planners.DEPLOY_PLANNERS if kind == "deploy" else planners.COLLECT_PLANNERS
        name = self.name(kind)
        if name not in registry:
            raise ExecutionError(
                f"unknown {kind} planner {name!r}; choose one of {', '.join(sorted(registry))}"
            )
        if hasattr(problem, "budget_ms"):
            named = problem.budget_ms
            if kind in self.planned:  # a replan: the fleet is waiting
                budget = replan_budget(named)
            elif kind == "deploy":  # the first deployment plan: the rovers are still on the deck
                budget = offline_budget(named)
            else:  # the first collection plan: the rovers hover, so only a budget asked for
                budget = named
            if budget != named:
                problem = dataclasses.replace(problem, budget_ms=budget)
        self.planned.add(kind)
        try:
            plan = await asyncio.to_thread(registry[name], problem)
        except PlanningError as exc:
            raise ExecutionError(
                f"cannot plan the {'deployment' if kind == 'deploy' else 'collection'} with {name!r}: {exc}"
            ) from None
        check_plan(plan, self.ctx.mission.geofence)  # ExecutionError naming the stop/rover outside it
        doc = plan.to_json()
        await self.ctx.commit(Ev.PLAN, plan=doc)
        self.ctx.state.set_plan(doc)  # the views (map, time to go); its start is set when it flies
        if self.write_plan is not None:
            self.write_plan(kind, plan)
        self.ctx.state.event(
            Ev.PLAN,
            f"{kind} plan ({name}): {len(plan.stops)} stops, makespan "
            f"{plan.makespan:.1f} s, computed in {plan.compute_ms:.0f} ms",
            stops=len(plan.stops),
            makespan=plan.makespan,
        )
        return plan

    def compile(self, plan: Plan) -> CompiledPlan:
        try:
            return compile_for_fleet(plan, self.ctx.fleet, meet_height=COLLECT_MEET_HEIGHT)
        except CompileError as exc:
            raise ExecutionError(str(exc)) from None


__all__ = ["COLLECT_MEET_HEIGHT", "REPLAN_BUDGET_MS", "Planning"]
