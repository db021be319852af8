"""``fleetctl plan``: plan offline from the mission file and print the summary or the plan JSON,
draw it (``--plot``), export it (``--export``). One carrier's plan, several teams' (docs/teams.md)
or a long operation's (docs/operations.md).

Imported when the command runs; matplotlib (``--plot``) and the MAVLink compiler (``--export``,
pymavlink) are imported only by the option that needs them.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections.abc import Callable
from contextlib import AbstractContextManager
from pathlib import Path
from typing import Any

import planners
from fleetctl.cli.common import warn_mission
from fleetctl.cli.errors import CliError
from fleetctl.mission import Mission, load_mission
from fleetctl.mission.formats.plan_export import export_plan
from fleetctl.mission.teams import several_teams
from fleetctl.operation_plan import plan_for_operation, print_operation_summary
from fleetctl.run.budget import offline_budget
from fleetctl.teams_plan import plan_for_teams, print_teams_summary
from fleetctl.views.plan_summary import print_plan_summary
from planners import PlanningError
from planners.core.plan import Plan
from planners.core.problem import CollectProblem, DeployProblem
from planners.operations import OPERATION_PLANNERS

Planner = Callable[[Any], Plan]


def cmd_plan(args: argparse.Namespace) -> int:
    mission = load_mission(args.mission)
    warn_mission(mission, args.collect)
    if mission.operation:  # a long operation: sorties, pick-ups and swaps (docs/operations.md)
        return _plan_operation(args, mission)
    registry: dict[str, Planner] = dict(planners.COLLECT_PLANNERS if args.collect
                                        else planners.DEPLOY_PLANNERS)
    phase = "collect" if args.collect else "deploy"
    name = args.planner or mission.planner_for(phase)
    if not args.planner and name == "lee-graph" and not (mission.raw.get("planner") or {}).get(phase):
        print(f"{args.mission}: the mission has obstacles and names no {phase} planner: using lee-graph",
              file=sys.stderr)
    if name not in registry:
        raise CliError(f"unknown planner {name!r} for {'collection' if args.collect else 'deployment'}; "
                       f"choose one of: {', '.join(sorted(registry))}")
    if several_teams(mission):  # carriers: [...] with more than one carrier (docs/teams.md)
        return _plan_teams(args, mission, registry[name], name)
    return _plan_one(args, mission, registry[name], name)


def _plan_one(args: argparse.Namespace, mission: Mission, planner: Planner, name: str) -> int:
    """``plan`` of one carrier: the plan within the budget, its lower bound, the report."""
    problem: DeployProblem | CollectProblem = (mission.collect_problem() if args.collect
                                               else mission.deploy_problem())
    named = args.budget_ms if args.budget_ms is not None else problem.budget_ms
    try:
        problem = dataclasses.replace(problem, budget_ms=offline_budget(named))
    except ValueError as e:
        raise CliError(str(e)) from None
    try:
        with _planning(mission, name):
            plan = planner(problem)
            bound = _lower_bound(problem)
    except PlanningError as e:
        raise CliError(f"{args.mission}: cannot plan with {name!r}: {e}") from None

    def draw(out: str) -> Path:
        from fleetctl.views.plot import plot_plan  # matplotlib: only for --plot

        return plot_plan(mission, plan, out, bound)

    _report(args, plan.to_json(), lambda: print_plan_summary(mission, plan, bound), draw)
    if args.export:
        files = _export(mission, plan, args.export)
        print(f"exported {len(files) - 1} QGroundControl .plan files and {files[-1].name} to {args.export}",
              file=sys.stderr if args.json else sys.stdout)
    return 0


def _plan_operation(args: argparse.Namespace, mission: Mission) -> int:
    """``plan`` on a long operation (``operation: true``; docs/operations.md)."""
    name = args.planner or "operation"
    for option, given in (("--collect", args.collect), ("--export", args.export), ("--plot", args.plot),
                          ("--budget-ms", args.budget_ms is not None)):
        if given:
            raise CliError(f"{args.mission}: {option} does not apply to a long operation yet")
    if name not in OPERATION_PLANNERS:
        raise CliError(f"unknown planner {name!r} for an operation; choose one of: "
                       f"{', '.join(sorted(OPERATION_PLANNERS))}")
    try:
        with _planning(mission, name):
            plan, bound = plan_for_operation(mission, name)
    except PlanningError as e:
        raise CliError(f"{args.mission}: cannot plan the operation with {name!r}: {e}") from None
    _report(args, plan.to_json(), lambda: print_operation_summary(mission, plan, bound), lambda out: out)
    return 0


def _plan_teams(args: argparse.Namespace, mission: Mission, planner: Planner, name: str) -> int:
    """``plan`` on a mission with several carriers (docs/teams.md)."""
    if args.export:
        raise CliError(f"{args.mission}: --export writes one carrier's plan; exporting several teams "
                       "is not supported yet")
    try:
        with _planning(mission, name):
            plan, bound = plan_for_teams(mission, args.collect, planner, name)
    except PlanningError as e:
        raise CliError(f"{args.mission}: cannot plan with {name!r}: {e}") from None

    def draw(out: str) -> Path:
        from fleetctl.views.plot_teams import plot_teams  # matplotlib: only for --plot

        return plot_teams(mission, plan, out, bound)

    _report(args, plan.to_json(), lambda: print_teams_summary(mission, plan, bound), draw)
    return 0


def _planning(mission: Mission, name: str) -> AbstractContextManager[object]:
    """A spinner on a terminal's stderr while the planner works (a 1,000-task mission takes seconds);
    nothing when stderr is a pipe or a file."""
    from rich.console import Console

    n = len(mission.tasks)
    return Console(stderr=True).status(f"planning {n} task{'s' if n != 1 else ''} with {name}…")


def _report(args: argparse.Namespace, doc: dict[str, Any], summary: Callable[[], None],
            draw: Callable[[str], object]) -> None:
    """The plan JSON on stdout (``--json``) or the summary, and the plot (``--plot``)."""
    if args.json:
        json.dump(doc, sys.stdout, indent=1)
        sys.stdout.write("\n")
    else:
        summary()
    if args.plot:
        out = draw(args.plot)
        print(f"plot written to {out}", file=sys.stderr if args.json else sys.stdout)


def _export(mission: Mission, plan: Plan, out_dir: str) -> list[Path]:
    """``--export DIR``: the mission items the controller would upload (compile_plan, no autopilot
    known offline) as <vehicle>.plan, and plan.geojson (docs/formats.md)."""
    from fleetctl.mavlink.compile import CompileError, compile_plan  # pymavlink: only for --export
    from fleetctl.run.planning import COLLECT_MEET_HEIGHT

    if mission.origin is None:
        raise CliError(f"{mission.path or mission.name}: --export needs the mission's origin (QGroundControl "
                       "plans and GeoJSON are in latitude/longitude); add origin: {lat, lon, alt}")
    try:
        compiled = compile_plan(plan, mission.origin, carrier_id=mission.carrier.id,
                                meet_height=COLLECT_MEET_HEIGHT)
        return export_plan(mission, plan, compiled, out_dir)
    except CompileError as e:
        raise CliError(f"cannot export the plan: {e}") from None
    except OSError as e:
        raise CliError(f"cannot write the export to {out_dir}: {e.strerror or e}") from None


def _lower_bound(problem: DeployProblem | CollectProblem) -> float:
    if isinstance(problem, CollectProblem):
        return float(planners.collect_lower_bound(problem))
    return float(planners.deploy_lower_bound(problem))
