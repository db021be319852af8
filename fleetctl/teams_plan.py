"""``fleetctl plan`` on a mission with several carriers (docs/teams.md): share the tasks (or the
rovers to collect) between the teams, plan each team, and the summary the command prints."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from fleetctl.mission import Mission
from fleetctl.mission.teams import teams_problem
from planners.core.plan import Plan
from planners.teams import TeamsPlan, TeamsProblem, plan_teams, teams_lower_bound


def share_teams(problem: TeamsProblem, planner: Callable[[Any], Plan], name: str) -> TeamsPlan:
    """``plan_teams`` with the planner's screening form when it has one (``planners.SCREEN_PLANNERS``):
    every controller of a mission shares its work this way, so that they all agree."""
    from planners import SCREEN_PLANNERS

    return plan_teams(problem, planner, name, screen=SCREEN_PLANNERS[problem.kind].get(name))


def plan_for_teams(mission: Mission, collect: bool, planner: Callable[[Any], Plan],
                   name: str) -> tuple[TeamsPlan, float]:
    """Share the work between the teams and plan each; the plan and its lower bound (a
    PlanningError goes to the caller)."""
    problem = teams_problem(mission, "collect" if collect else "deploy")
    return share_teams(problem, planner, name), teams_lower_bound(problem)


def print_teams_summary(mission: Mission, plan: TeamsPlan, bound: float) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    kind = "Deployment" if plan.kind == "deploy" else "Collection"
    table = Table(title=f"{kind} plan for {mission.name}: {len(plan.teams)} teams ({plan.planner})",
                  title_justify="left")
    for col in ("carrier", "stop", "position (E, N) m", "arrive s", "depart s"):
        table.add_column(col, justify="right" if col in ("stop", "arrive s", "depart s") else "left")
    table.add_column("rovers" if plan.kind == "collect" else "rover → task")
    table.add_column("rover arrival s", justify="right")
    for team in plan.teams:
        for k, stop in enumerate(team.plan.stops, 1):
            who = ", ".join(f"{leg.rover}→{leg.task}" if plan.kind == "deploy" else leg.rover
                            for leg in stop.rovers)
            latest = max((leg.arrive for leg in stop.rovers), default=0.0)
            where = f"{stop.position[0]:.1f}, {stop.position[1]:.1f}"
            table.add_row(team.carrier if k == 1 else "", str(k), where, f"{stop.arrive:.2f}",
                          f"{stop.depart:.2f}", who, f"{latest:.2f}")
        table.add_section()
    console.print(table)
    for team in plan.teams:
        p = team.plan
        console.print(f"team {team.carrier:<10} makespan {p.makespan:8.2f} s, {len(p.legs())} rovers, "
                      f"{len(p.stops)} stops, carrier travels {p.carrier_distance:.2f} m")
    console.print(f"makespan        {plan.makespan:.2f} s (the latest team's)")
    if plan.baseline_makespan is not None:
        what = "task" if plan.kind == "deploy" else "rover"
        console.print(f"nearest carrier {plan.baseline_makespan:.2f} s "
                      f"(every {what} to the carrier starting nearest)")
    gap = (plan.makespan - bound) / plan.makespan * 100 if plan.makespan > 0 else 0.0
    console.print(f"lower bound     {bound:.2f} s (plan is within {gap:.1f} % of it)")
    console.print(f"computed in     {plan.compute_ms:.1f} ms")
