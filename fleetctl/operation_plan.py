"""``fleetctl plan`` on a long operation (docs/operations.md): the mission's operation problem,
its plan by the named planner with the lower bound, and the summary the command prints."""

from __future__ import annotations

from fleetctl.mission import Mission
from planners.operations import OPERATION_PLANNERS, OperationPlan, operation_lower_bound


def plan_for_operation(mission: Mission, name: str) -> tuple[OperationPlan, float]:
    """The operation planned by ``name`` (``operation`` or ``waves``) and its lower bound (a
    PlanningError goes to the caller)."""
    problem = mission.operation_problem()
    return OPERATION_PLANNERS[name](problem), operation_lower_bound(problem)


def print_operation_summary(mission: Mission, plan: OperationPlan, bound: float) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    table = Table(title=f"Operation plan for {mission.name} ({plan.planner})", title_justify="left")
    for col in ("stop", "position (E, N) m", "arrive s", "depart s", "picks up", "launches rover → tasks"):
        table.add_column(col, justify="right" if col in ("stop", "arrive s", "depart s") else "left")
    tasks_of = {(s.rover, s.launch_stop): [v.task for v in s.visits] for s in plan.sorties}
    for k, stop in enumerate(plan.stops, 1):
        launches = ", ".join(f"{r}→{'+'.join(tasks_of[(r, k - 1)])}" for r in stop.launches)
        table.add_row(str(k), f"{stop.position[0]:.1f}, {stop.position[1]:.1f}", f"{stop.arrive:.1f}",
                      f"{stop.depart:.1f}", ", ".join(stop.pickups), launches)
    console.print(table)
    lowest = min((s.battery_left for s in plan.sorties), default=1.0)
    console.print(f"operation ends  {plan.makespan:.1f} s (every task worked, every rover on the deck)")
    console.print(f"sorties         {len(plan.sorties)} by {len({s.rover for s in plan.sorties})} rovers, "
                  f"{len(plan.swaps)} battery swaps, lowest battery {100 * lowest:.0f} %")
    console.print(f"carrier travels {plan.carrier_distance:.1f} m over {len(plan.stops)} stops")
    gap = (plan.makespan - bound) / plan.makespan * 100 if plan.makespan > 0 else 0.0
    console.print(f"lower bound     {bound:.1f} s (plan is within {gap:.1f} % of it)")
    console.print(f"computed in     {plan.compute_ms:.1f} ms")
