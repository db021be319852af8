"""What ``fleetctl plan`` prints of one carrier's plan: a table of its stops, then the makespan,
the carrier's distance, the lower bound and the planning time (docs/cli.md#fleetctl-plan)."""

from __future__ import annotations

from fleetctl.mission import Mission
from planners.core.plan import Plan


def gap_percent(makespan: float, bound: float) -> float:
    """How far above ``bound`` a plan of ``makespan`` is, in percent of the makespan."""
    return (makespan - bound) / makespan * 100 if makespan > 0 else 0.0


def stop_rows(plan: Plan) -> list[tuple[str, ...]]:
    """One row per stop: number, position, arrival, departure, who, the latest rover's arrival."""
    rows: list[tuple[str, ...]] = []
    for k, stop in enumerate(plan.stops, 1):
        if plan.kind == "deploy":
            who = ", ".join(f"{leg.rover}→{leg.task}" for leg in stop.rovers)
        else:
            who = ", ".join(leg.rover for leg in stop.rovers)
        latest = max((leg.arrive for leg in stop.rovers), default=0.0)
        rows.append((str(k), f"{stop.position[0]:.1f}, {stop.position[1]:.1f}", f"{stop.arrive:.2f}",
                     f"{stop.depart:.2f}", who, f"{latest:.2f}"))
    return rows


def print_plan_summary(mission: Mission, plan: Plan, bound: float | None) -> None:
    """The table and the figures, on stdout (rich, imported here: only a summary needs it)."""
    from rich.console import Console
    from rich.table import Table

    console = Console()
    kind = "Deployment" if plan.kind == "deploy" else "Collection"
    table = Table(title=f"{kind} plan for {mission.name} ({plan.planner})", title_justify="left")
    table.add_column("stop", justify="right")
    table.add_column("position (E, N) m")
    table.add_column("arrive s", justify="right")
    table.add_column("depart s", justify="right")
    table.add_column("rovers" if plan.kind == "collect" else "rover → task")
    table.add_column("rover arrival s", justify="right")
    for row in stop_rows(plan):
        table.add_row(*row)
    console.print(table)
    console.print(f"makespan        {plan.makespan:.2f} s")
    console.print(f"carrier travels {plan.carrier_distance:.2f} m over {len(plan.stops)} stops")
    if bound is not None:
        gap = gap_percent(plan.makespan, bound)
        console.print(f"lower bound     {bound:.2f} s (plan is within {gap:.1f} % of it)")
    console.print(f"computed in     {plan.compute_ms:.1f} ms")
