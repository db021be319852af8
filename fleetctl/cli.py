"""The ``fleetctl`` command line (DESIGN.md "Command line — the contract")."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from collections.abc import Sequence

from fleetctl.mission import Mission, MissionError, load_mission

log = logging.getLogger("fleetctl")

EXIT_USAGE = 2


class CliError(Exception):
    """A problem the user can fix; printed as one line, exit status 2."""


def _planners(collect: bool) -> dict:
    import planners

    if collect:
        registry = getattr(planners, "COLLECT_PLANNERS", None)
        if registry is None:
            raise CliError("collection planning is not available in this version")
        return registry
    return planners.DEPLOY_PLANNERS


def cmd_plan(args: argparse.Namespace) -> int:
    from planners import PlanningError

    mission = load_mission(args.mission)
    registry = _planners(args.collect)
    name = args.planner or (mission.planner.collect if args.collect else mission.planner.deploy)
    if name not in registry:
        raise CliError(f"unknown planner {name!r} for {'collection' if args.collect else 'deployment'}; "
                       f"choose one of: {', '.join(sorted(registry))}")
    problem = mission.collect_problem() if args.collect else mission.deploy_problem()
    try:
        plan = registry[name](problem)
        bound = _lower_bound(problem, args.collect)
    except PlanningError as e:
        raise CliError(f"{args.mission}: cannot plan with {name!r}: {e}") from None
    if args.json:
        json.dump(plan.to_json(), sys.stdout, indent=1)
        sys.stdout.write("\n")
    else:
        _print_summary(mission, plan, bound)
    if args.plot:
        from fleetctl.plot import plot_plan

        out = plot_plan(mission, plan, args.plot, bound)
        print(f"plot written to {out}", file=sys.stderr if args.json else sys.stdout)
    return 0


def _lower_bound(problem: object, collect: bool) -> float | None:
    import planners

    fn = getattr(planners, "collect_lower_bound", None) if collect else planners.deploy_lower_bound
    return fn(problem) if fn is not None else None


def _print_summary(mission: Mission, plan: object, bound: float | None) -> None:
    from rich.console import Console
    from rich.table import Table

    from planners.plan import Plan

    assert isinstance(plan, Plan)
    console = Console()
    kind = "Deployment" if plan.kind == "deploy" else "Collection"
    table = Table(title=f"{kind} plan for {mission.name} ({plan.planner})", title_justify="left")
    table.add_column("stop", justify="right")
    table.add_column("position (E, N) m")
    table.add_column("arrive s", justify="right")
    table.add_column("depart s", justify="right")
    table.add_column("rovers" if plan.kind == "collect" else "rover → task")
    table.add_column("rover arrival s", justify="right")
    for k, stop in enumerate(plan.stops, 1):
        if plan.kind == "deploy":
            who = ", ".join(f"{leg.rover}→{leg.task}" for leg in stop.rovers)
        else:
            who = ", ".join(leg.rover for leg in stop.rovers)
        latest = max((leg.arrive for leg in stop.rovers), default=0.0)
        table.add_row(str(k), f"{stop.position[0]:.1f}, {stop.position[1]:.1f}", f"{stop.arrive:.2f}",
                      f"{stop.depart:.2f}", who, f"{latest:.2f}")
    console.print(table)
    console.print(f"makespan        {plan.makespan:.2f} s")
    console.print(f"carrier travels {plan.carrier_distance:.2f} m over {len(plan.stops)} stops")
    if bound is not None:
        gap = (plan.makespan - bound) / plan.makespan * 100 if plan.makespan > 0 else 0.0
        console.print(f"lower bound     {bound:.2f} s (plan is within {gap:.1f} % of it)")
    console.print(f"computed in     {plan.compute_ms:.1f} ms")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="fleetctl",
        description="Mission controller for a marsupial drone team: a carrier vehicle deploys UAV "
                    "rovers near their tasks and collects them again, over MAVLink.",
    )
    p.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    plan = sub.add_parser(
        "plan", help="plan a deployment (or collection) offline and show it",
        description="Plan offline from the mission file: which stops the carrier makes, which rover "
                    "it drops (or picks up) there, and when everyone arrives. Prints a readable "
                    "summary, or the plan JSON with --json.",
    )
    plan.add_argument("--mission", "-m", required=True, help="mission YAML file (see missions/)")
    plan.add_argument("--collect", action="store_true",
                      help="plan the collection of the mission's 'collection' rovers "
                           "instead of the deployment")
    plan.add_argument("--planner", "-p",
                      help="deployment: lee (default), greedy2opt, direct, two-task; "
                           "collection: lee (default), lee-convex, visit-all, gather")
    plan.add_argument("--json", action="store_true", help="print only the plan JSON (schema fleetctl.plan/1)")
    plan.add_argument("--plot", metavar="OUT.png", help="draw the plan to a PNG file")
    plan.set_defaults(func=cmd_plan)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    try:
        return int(args.func(args) or 0)
    except (MissionError, CliError) as e:
        print(f"fleetctl: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("fleetctl: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
