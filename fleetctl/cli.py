"""The ``fleetctl`` command line (docs/cli.md)."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import logging
import sys
from collections.abc import AsyncIterator, Callable, Sequence
from typing import TYPE_CHECKING, Any

from fleetctl import package_version
from fleetctl.mission import Mission, MissionError, load_mission
from fleetctl.mission.limits import MAX_BUDGET_MS
from fleetctl.mission.outliers import far_task_warnings
from fleetctl.mission.teams import several_teams
from fleetctl.run.budget import DEFAULT_BUDGET_MS, offline_budget
from planners.core.problem import CollectProblem

if TYPE_CHECKING:
    from fleetctl.run.lifecycle import RunOutcome
    from planners.core.problem import DeployProblem

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
    _warn(mission, args.collect)
    if mission.operation:  # a long operation: sorties, pick-ups and swaps (docs/operations.md)
        return _plan_operation(args, mission)
    registry = _planners(args.collect)
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
    problem = mission.collect_problem() if args.collect else mission.deploy_problem()
    named = args.budget_ms if args.budget_ms is not None else problem.budget_ms
    try:
        problem = dataclasses.replace(problem, budget_ms=offline_budget(named))
    except ValueError as e:
        raise CliError(str(e)) from None
    try:
        plan = registry[name](problem)
        bound = _lower_bound(problem, args.collect)
    except PlanningError as e:
        raise CliError(f"{args.mission}: cannot plan with {name!r}: {e}") from None
    def draw(out: str) -> Any:
        from fleetctl.views.plot import plot_plan

        return plot_plan(mission, plan, out, bound)

    _report(args, plan.to_json(), lambda: _print_summary(mission, plan, bound), draw)
    if args.export:
        files = _export(mission, plan, args.export)
        print(f"exported {len(files) - 1} QGroundControl .plan files and {files[-1].name} to {args.export}",
              file=sys.stderr if args.json else sys.stdout)
    return 0


def _plan_operation(args: argparse.Namespace, mission: Mission) -> int:
    """``plan`` on a long operation (``operation: true``; docs/operations.md)."""
    from fleetctl.operation_plan import plan_for_operation, print_operation_summary
    from planners import PlanningError
    from planners.operations import OPERATION_PLANNERS

    name = args.planner or "operation"
    for option, given in (("--collect", args.collect), ("--export", args.export), ("--plot", args.plot),
                          ("--budget-ms", args.budget_ms is not None)):
        if given:
            raise CliError(f"{args.mission}: {option} does not apply to a long operation yet")
    if name not in OPERATION_PLANNERS:
        raise CliError(f"unknown planner {name!r} for an operation; choose one of: "
                       f"{', '.join(sorted(OPERATION_PLANNERS))}")
    try:
        plan, bound = plan_for_operation(mission, name)
    except PlanningError as e:
        raise CliError(f"{args.mission}: cannot plan the operation with {name!r}: {e}") from None
    _report(args, plan.to_json(), lambda: print_operation_summary(mission, plan, bound), lambda out: out)
    return 0


def _plan_teams(args: argparse.Namespace, mission: Mission, planner: Any, name: str) -> int:
    """``plan`` on a mission with several carriers (docs/teams.md)."""
    from fleetctl.teams_plan import plan_for_teams, print_teams_summary
    from planners import PlanningError

    if args.export:
        raise CliError(f"{args.mission}: --export writes one carrier's plan; exporting several teams "
                       "is not supported yet")
    try:
        plan, bound = plan_for_teams(mission, args.collect, planner, name)
    except PlanningError as e:
        raise CliError(f"{args.mission}: cannot plan with {name!r}: {e}") from None

    def draw(out: str) -> Any:
        from fleetctl.views.plot_teams import plot_teams

        return plot_teams(mission, plan, out, bound)

    _report(args, plan.to_json(), lambda: print_teams_summary(mission, plan, bound), draw)
    return 0


def _report(args: argparse.Namespace, doc: dict[str, Any], summary: Callable[[], None],
            draw: Callable[[str], Any]) -> None:
    """The plan JSON on stdout (``--json``) or the summary, and the plot (``--plot``)."""
    if args.json:
        json.dump(doc, sys.stdout, indent=1)
        sys.stdout.write("\n")
    else:
        summary()
    if args.plot:
        out = draw(args.plot)
        print(f"plot written to {out}", file=sys.stderr if args.json else sys.stdout)


def _warn(mission: Mission, collect: bool) -> None:
    """Warnings about a mission that loads but looks wrong (a task far outside the others)."""
    for line in [] if collect else far_task_warnings(mission):
        print(f"fleetctl: warning: {mission.path or mission.name}: {line}", file=sys.stderr)


def _export(mission: Mission, plan: Any, out_dir: str) -> list[Any]:
    """``--export DIR``: the mission items the controller would upload (compile_plan, no autopilot
    known offline) as <vehicle>.plan, and plan.geojson (docs/formats.md)."""
    from fleetctl.mavlink.compile import CompileError, compile_plan
    from fleetctl.mission.formats.plan_export import export_plan
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


def _lower_bound(problem: DeployProblem | CollectProblem, collect: bool) -> float | None:
    import planners

    if isinstance(problem, CollectProblem):
        return float(planners.collect_lower_bound(problem))
    return float(planners.deploy_lower_bound(problem))


def _print_summary(mission: Mission, plan: object, bound: float | None) -> None:
    from rich.console import Console
    from rich.table import Table

    from planners.core.plan import Plan

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


# ---------------------------------------------------------------------------- flying (deploy, collect, run)

_FLY_EPILOG = """\
connection: sim starts the embedded simulated fleet in this process (at the mission's sim.speedup,
or --speedup). Its rovers start on the carrier's deck, so 'collect' on a sim mission first places
the rovers named in the mission's 'collection:' section at their positions there (with the battery
their 'range' implies; the others stay on the deck) and refuses a mission without that section -
fly 'run' to deploy, dwell and collect in one go.

Records: runs/<mission>-<timestamp>/ (or --run-dir DIR, named on the first output line) holds
journal.jsonl (written ahead of every command), traffic.tlog (all MAVLink traffic), mission.yaml
(a copy of the mission), plan.json, export/ (the plan as QGroundControl .plan files and GeoJSON)
and summary.json (schema fleetctl.summary/1; also --summary).
Exit status: 0 mission complete, 1 not complete (or a vehicle did not answer, an upload was
rejected), 2 bad mission file or option, 130 interrupted by Ctrl-C, 143 by SIGTERM (airborne
rovers were told to hold; 'fleetctl resume --run DIR' finishes the run).
"""


EXIT_TERMINATED = 143  # SIGTERM: like Ctrl-C (airborne rovers hold, records written)


def cmd_fly(args: argparse.Namespace) -> int:
    mission = load_mission(args.mission)
    _warn(mission, args.command == "collect")
    if mission.operation and args.command != "run":
        raise CliError(f"{mission.path}: operation: a long operation is flown whole, its sorties "
                       f"deploying and collecting rovers in turn: fly it with "
                       f"'fleetctl run --mission {args.mission}' (docs/operations.md)")
    if args.command in ("deploy", "run") and not mission.tasks:
        raise CliError(f"{mission.path}: tasks: the mission has no tasks to deploy rovers to (a collection-"
                       f"only mission); fly it with 'fleetctl collect --mission {args.mission}'")
    return _fly(args, mission, args.command, {"run_dir": args.run_dir, "runs_dir": args.runs})


def cmd_resume(args: argparse.Namespace) -> int:
    from fleetctl.run.resume import ResumeError, load_resumption
    from fleetctl.run.resume_teams import is_teams_run, load_teams_resumption

    team = None
    try:
        if is_teams_run(args.run):  # a run of several teams in one controller (docs/teams.md#resume)
            teams = load_teams_resumption(args.run, args.mission)
            resumption: Any = teams
            extra: dict[str, Any] = {"teams_resume": teams}
        else:
            team = _resumed_team(args)  # a --team controller's run: that team again
            resumption = team[1] if team is not None else load_resumption(args.run, args.mission)
            extra = {"resume": resumption}
    except ResumeError as e:
        raise CliError(str(e)) from None
    mission = team[0] if team is not None else resumption.mission
    if mission.operation:
        raise CliError(f"{args.run}: resuming a long operation is not supported yet; fly it again with "
                       f"'fleetctl run' once the rovers are back on the deck (docs/operations.md)")
    if team is None and several_teams(mission) and "resume" in extra:
        raise CliError(f"{args.run}: the mission has {len(mission.teams)} carriers and the journal's run "
                       "record names neither its teams (every team in one controller) nor the team it flew "
                       "(--team ID); it cannot be told what to resume")
    for key in ("planner", "dwell"):  # the interrupted run's choices, unless given again
        if getattr(args, key, None) is None:
            setattr(args, key, resumption.options.get(key))
    return _fly(args, mission, resumption.command, extra)


def _resumed_team(args: argparse.Namespace) -> tuple[Mission, Any] | None:
    """``resume`` of a ``--team ID`` controller's run folder (its ``run`` record names the team):
    the whole mission and the :class:`~fleetctl.run.resume.Resumption` of that team's run, over
    the team's share (the allocation every team's controller computes alike) or, for ``collect
    --team``, its deck; ``args`` get ``team`` and the interrupted run's planner and dwell. None
    for any other run folder."""
    from pathlib import Path

    from fleetctl.mission.teams import team_mission
    from fleetctl.run.resume import ResumeError, read_records, read_run, resumption_of
    from fleetctl.run.teams.own_controller import team_shares
    from planners import PlanningError

    path = Path(args.run) / "journal.jsonl"
    if not path.is_file():
        return None
    run = next((r for r in read_records(path) if r["kind"] == "run"), None)
    if run is None or not isinstance(run.get("team"), str):
        return None
    d, records, run, whole = read_run(args.run, args.mission)
    team, command = str(run["team"]), str(run["command"])
    for key in ("planner", "dwell"):  # the interrupted run's choices, unless given again
        if getattr(args, key, None) is None:
            setattr(args, key, run.get(key))
    args.team = team
    try:
        tasks = () if command == "collect" else team_shares(whole, args.planner).get(team, [])
        own = team_mission(whole, team, tasks=tasks)
    except (MissionError, KeyError, PlanningError) as e:
        raise ResumeError(f"{d}: cannot fly team {team} of {whole.path or whole.name} again: {e}") from None
    return whole, resumption_of(d, records, command, own, float(run.get("speedup") or 1.0),
                                {"planner": run.get("planner"), "dwell": run.get("dwell")})


def _fly(args: argparse.Namespace, mission: Mission, command: str, extra: dict[str, Any]) -> int:
    import asyncio

    from fleetctl.run.context import ExecutionError
    from fleetctl.run.lifecycle import EXIT_INTERRUPTED
    from fleetctl.views.dashboard import make_view

    team = getattr(args, "team", None)
    if args.speedup is not None and args.speedup <= 0:
        raise CliError(f"--speedup must be > 0, got {args.speedup}")
    if getattr(args, "dwell", None) is not None and args.dwell < 0:
        raise CliError(f"--dwell must be >= 0 s, got {args.dwell}")
    if args.budget_ms is not None:  # every plan of the run (replans: at most budget.REPLAN_BUDGET_MS)
        planner = dataclasses.replace(mission.planner, budget_ms=args.budget_ms)
        mission = dataclasses.replace(mission, planner=planner)
    mqtt = _bus_config(mission, args)
    spec = None
    if team is not None and command == "collect":
        mission, mqtt = _collecting_team(mission, team, mqtt)
    elif team is not None:
        mission, spec, mqtt = _team(mission, team, args, mqtt)
    view = _with_web(args, make_view(True if args.headless else None, latlon=args.latlon), mission.origin)

    def announce(run_dir: object) -> None:
        print(f"run folder: {run_dir}", flush=True)

    options = dict(speedup=args.speedup, planner=args.planner, dwell=getattr(args, "dwell", None),
                   summary_path=args.summary, view=view, connect_timeout=args.timeout, mqtt=mqtt,
                   on_run_dir=announce, require_all=args.require_all, force=args.force,
                   confirm=_arming_confirmation(args, mission, command), team_spec=spec, team=team,
                   **extra)
    if args.speedup is not None and mission.carrier.connection != "sim":  # SITL firmware run faster
        options["clock_speedup"] = args.speedup
    try:
        outcome, terminated = asyncio.run(_with_sigterm(mission, command, options))
    except ExecutionError as e:  # raised before anything flew (e.g. collect on a sim mission)
        raise CliError(str(e)) from None
    _print_outcome(command, mission, outcome)
    if terminated and outcome.exit_code == EXIT_INTERRUPTED:
        return EXIT_TERMINATED
    return outcome.exit_code


def _collecting_team(mission: Mission, team: str, mqtt: Any) -> tuple[Mission, Any]:
    """``collect --team ID``: the team's carrier collects the rovers of its deck (its own
    controller, its own bus prefix ``P/teams/ID``; nothing to coordinate)."""
    from fleetctl.mission.teams import team_mission
    from fleetctl.run.teams.own_controller import team_bus_config

    try:
        own = team_mission(mission, team, tasks=())
    except MissionError as e:
        raise CliError(str(e)) from None
    print(f"team {team}: collecting {', '.join(u.id for u in own.rovers.units)} with {team}", flush=True)
    return own, team_bus_config(mqtt, team)


def _team(mission: Mission, team: str, args: argparse.Namespace, mqtt: Any) -> tuple[Mission, Any, Any]:
    """``--team ID``: the team's own mission, the coordination spec, the team's bus settings."""
    from fleetctl.run.teams.own_controller import prepare_team
    from planners import PlanningError

    try:
        own, spec, config = prepare_team(mission, team, args.planner, mqtt)
    except MissionError as e:
        raise CliError(str(e)) from None
    except KeyError as e:
        raise CliError(f"unknown deploy planner {e}") from None
    except PlanningError as e:
        where = mission.path or mission.name
        raise CliError(f"{where}: cannot share the tasks between the teams: {e}") from None
    share = ", ".join(spec.shares.get(team, [])) or "none"
    if config is None:
        print(f"fleetctl: warning: --team {team} without an MQTT bus (--mqtt URL or the mission's mqtt: "
              f"section): flying team {team}'s share ({share}) with no coordination; if it fails its "
              "tasks are not handed over to the other teams", file=sys.stderr)
    else:
        print(f"team {team}: share {share}; coordinating on {config.url} under {spec.prefix}", flush=True)
    return own, spec, config


def _arming_confirmation(args: argparse.Namespace, mission: Mission,
                         command: str) -> Callable[[list[str]], bool] | None:
    """Real vehicles are armed only on a decision: asked on a terminal, or --yes."""
    from fleetctl.run.sim import mission_uses_sim

    if args.yes or mission_uses_sim(mission):
        return None
    if not sys.stdin.isatty():
        raise CliError(f"{command} would arm real vehicles ({mission.carrier.connection}) and there is no "
                       "terminal to confirm it on; pass --yes to arm without asking")

    def ask(lines: list[str]) -> bool:
        print(f"fleetctl {command} {mission.name}: these vehicles will be armed and flown:")
        for line in lines:
            print(f"  {line}")
        try:
            answer = input("arm and fly? [y/N] ")
        except EOFError:
            return False
        return answer.strip().lower() in ("y", "yes")

    return ask


async def _with_sigterm(mission: Mission, command: str, options: dict[str, Any]) -> tuple[RunOutcome, bool]:
    """Run the command; SIGTERM cancels it like Ctrl-C does (and is reported as such)."""
    import asyncio
    import contextlib
    import signal

    from fleetctl.run.flight import execute

    loop = asyncio.get_running_loop()
    task = asyncio.current_task()
    got: list[int] = []

    def on_term() -> None:
        got.append(signal.SIGTERM)
        if task is not None:
            task.cancel()

    # asyncio raises NotImplementedError where the platform has no Unix signals (Windows); there
    # Ctrl-C still ends the run through KeyboardInterrupt, so no SIGTERM handler is the right outcome
    with contextlib.suppress(NotImplementedError):
        loop.add_signal_handler(signal.SIGTERM, on_term)
    spec = options.pop("team_spec", None)
    try:
        if spec is not None:  # --team: one team of several (fleetctl.run.teams.own_controller)
            from fleetctl.run.teams.own_controller import execute_team

            outcome = await execute_team(mission, command, spec, **options)
        else:
            outcome = await execute(mission, command, **options)
    finally:
        with contextlib.suppress(NotImplementedError):  # (no handler was installed: see above)
            loop.remove_signal_handler(signal.SIGTERM)
    return outcome, bool(got)


def _print_outcome(command: str, mission: Mission, outcome: RunOutcome) -> None:
    s = outcome.summary
    if outcome.error:
        print(f"fleetctl: error: {outcome.error}", file=sys.stderr)
    n_tasks = len(s.get("tasks_reached", [])) + len(s.get("tasks_unserved", []))
    print(f"{command} {s['result']}: "
          + (f"{len(s['tasks_reached'])}/{n_tasks or len(mission.tasks)} tasks reached"
             if command != "collect" else f"{len(s['rovers_loaded'])} rovers loaded")
          + (f", {len(s['rovers_airborne'])} rovers airborne" if s.get("rovers_airborne") else "")
          + (f", makespan {s['makespan_flown']:.1f} s (planned {s['makespan_planned']:.1f} s)"
             if s.get("makespan_flown") is not None and s.get("makespan_planned") is not None else "")
          + f"; records in {outcome.run_dir}",
          file=sys.stderr if outcome.exit_code else sys.stdout)
    for team in s.get("teams", []):  # several carriers (docs/teams.md): a line per team
        print("  " + _team_line(team), file=sys.stderr if outcome.exit_code else sys.stdout)


def _team_line(team: dict[str, Any]) -> str:
    parts = [f"team {team['carrier']}" + (" (carrier lost)" if team.get("lost") else "")]
    for phase, what in (("deploy", "tasks_reached"), ("collect", "rovers_loaded")):
        p = team.get(phase)
        if p is None:
            continue
        n = len(p[what])
        of = (len(p["tasks_planned"]) + len(p["tasks_received"]) if phase == "deploy"
              else len(p["rovers_planned"]))
        got = f"{n}/{of} tasks reached" if phase == "deploy" else f"{n}/{of} rovers loaded"
        if phase == "deploy" and p["tasks_received"]:
            got += f" ({len(p['tasks_received'])} handed to it)"
        if p.get("makespan_flown") is not None and p.get("makespan_planned") is not None:
            got += f" in {p['makespan_flown']:.1f} s (planned {p['makespan_planned']:.1f} s)"
        parts.append(f"{phase}: {got}")
    return "; ".join(parts)


def _add_fly_commands(sub: argparse._SubParsersAction) -> None:
    helps = {
        "deploy": ("fly the deployment: drop every rover near its task",
                   "Connect to the mission's vehicles (or start the embedded simulated fleet for "
                   "connection: sim), plan the deployment from the carrier's live position, and fly it "
                   "stop by stop with a live terminal view."),
        "collect": ("fly the collection: pick every rover up again",
                    "Plan the collection from live telemetry (rover positions, battery-derived ranges) "
                    "and fly it: each rover flies above its meeting point and lands on the carrier."),
        "run": ("deploy, dwell on task, collect",
                "Fly the deployment, wait --dwell seconds with the rovers on task, then collect them."),
    }
    for name, (short, desc) in helps.items():
        p = sub.add_parser(name, help=short, description=desc, epilog=_FLY_EPILOG,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        p.add_argument("--mission", "-m", required=True, help="mission YAML file (see missions/)")
        p.add_argument("--headless", action="store_true",
                       help="one log line per event instead of the live view (automatic when stdout "
                            "is not a terminal)")
        p.add_argument("--speedup", type=float, metavar="X",
                       help="simulated seconds per wall second of the embedded sim (default: sim.speedup); "
                            "with real links, the vehicles' clock rate (SITL firmware run with --speedup X)")
        p.add_argument("--summary", metavar="OUT.json", help="also write the run summary JSON here")
        p.add_argument("--planner", "-p",
                       help="planner name (default: the mission's planner section); for run "
                            "DEPLOY,COLLECT names both, e.g. greedy2opt,visit-all")
        if name == "run":
            p.add_argument("--dwell", type=float, metavar="S",
                           help="seconds on task before collection (default: the mission's dwell)")
        if name != "collect":
            p.add_argument("--team", metavar="ID",
                           help="a mission with several carriers: fly only the team of carrier ID (its "
                                "share of the tasks), coordinating with the other teams' controllers over "
                                "the MQTT bus (docs/teams.md); without a bus it flies its share alone")
        else:
            p.add_argument("--team", metavar="ID",
                           help="a mission with several carriers: carrier ID collects the rovers of its "
                                "own deck only (one controller for that team; docs/teams.md)")
        p.add_argument("--runs", default="runs", metavar="DIR",
                       help="where run folders go (default: runs; each run gets runs/<mission>-<timestamp>)")
        p.add_argument("--run-dir", metavar="DIR",
                       help="the records folder of this run (default: a new folder under --runs); "
                            "printed as the first line of output; 'fleetctl resume --run DIR' finishes it")
        _add_shared_fly_options(p)
        p.set_defaults(func=cmd_fly)
    _add_resume_command(sub)


def _budget_ms(text: str) -> float:
    """``--budget-ms N``: milliseconds of anytime improvement search after the quick plan."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of milliseconds, got {text!r}") from None
    if not 0 <= value <= MAX_BUDGET_MS:
        raise argparse.ArgumentTypeError(f"must be 0..{MAX_BUDGET_MS:.0f} ms, got {text}")
    return value


def _add_budget_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--budget-ms", type=_budget_ms, metavar="N",
                   help="after the quick plan, improve it for about N ms (iterated local search, seeded "
                        "by planner.seed, ending sooner when it converges; 0: the quick plan; default: the "
                        f"mission's planner.budget_ms, else {DEFAULT_BUDGET_MS:.0f} ms for 'plan' and a "
                        "deployment's first plan, the quick plan for a collection (its rovers hover) and "
                        "for replans)")


def _add_shared_fly_options(p: argparse.ArgumentParser) -> None:
    _add_budget_option(p)
    p.add_argument("--timeout", type=float, default=10.0, metavar="S",
                   help="seconds to wait for every vehicle's first heartbeat (default: 10)")
    p.add_argument("--yes", "-y", action="store_true",
                   help="arm real vehicles without asking (needed without a terminal; the simulated "
                        "fleet never asks)")
    p.add_argument("--require-all", action="store_true",
                   help="refuse to fly when any rover does not answer (default: fly with the rovers "
                        "that answer when they are enough for the tasks)")
    p.add_argument("--force", action="store_true",
                   help="fly although another ground station is on the link or vehicles are already "
                        "armed or in a mission")
    _add_bus_options(p)
    _add_view_options(p)


_RESUME_EPILOG = """\
What it does: reads DIR/journal.jsonl (written ahead of every command, so it says what was
commanded up to the crash) and DIR/mission.yaml, reconnects to the live fleet, checks the journal
against telemetry (rovers on the deck, flying to their task, holding on it, landed elsewhere,
lost; where the carrier is), then finishes the interrupted phase - and for a 'run' the dwell and
the collection - with the same planners and replanning. It never launches a rover that is flying
and never serves a reached task again; it appends to the same journal (a 'resumed' record) and
writes DIR/summary.json for the whole run.

Several teams (carriers:) in one controller: each team's deployment goes on from its own journal
(DIR/teams/<carrier>/deploy/) over the tasks it owns now (its share and the hand-overs recorded in
DIR/journal.jsonl), then the dwell left, then the collection shared out again from the live fleet.
The run folder of a --team controller is resumed as that team's run (re-joining the bus with its
claims). docs/teams.md#resume says more.

It refuses (exit 2) a folder without a journal, a run that completed, a --mission that is not
the saved one, and a run on the embedded simulated fleet (connection: sim), which died with the
controller. Exit status otherwise as for deploy/collect/run.
"""


def _add_resume_command(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("resume", help="finish a run whose controller was killed or crashed",
                       description="Finish an interrupted deploy, collect or run from its records folder, "
                                   "on the live fleet.", epilog=_RESUME_EPILOG,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--run", required=True, metavar="DIR",
                   help="the run folder (printed when the run started)")
    p.add_argument("--mission", "-m", help="the mission file (default: the copy saved in the run folder; "
                                           "given, it must be the same)")
    p.add_argument("--headless", action="store_true", help="one log line per event instead of the live view")
    p.add_argument("--speedup", type=float, metavar="X", help=argparse.SUPPRESS)
    p.add_argument("--summary", metavar="OUT.json", help="also write the run summary JSON here")
    p.add_argument("--planner", "-p", help="planner name (default: the interrupted run's)")
    p.add_argument("--dwell", type=float, metavar="S",
                   help="run: seconds on task (default: the interrupted run's)")
    _add_shared_fly_options(p)
    p.set_defaults(func=cmd_resume)


class _Version(argparse.Action):
    """``--version``: read the package metadata only when asked."""

    def __init__(self, option_strings: Sequence[str], dest: str, **kw: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kw)

    def __call__(self, parser: argparse.ArgumentParser, *_: Any) -> None:
        print(f"fleetctl {package_version()}")
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="fleetctl",
        description="Mission controller for a marsupial drone team: a carrier vehicle deploys UAV "
                    "rovers near their tasks and collects them again, over MAVLink.",
    )
    p.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    p.add_argument("--version", action=_Version, help="print the fleetctl version and exit")
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
    _add_budget_option(plan)
    plan.add_argument("--json", action="store_true", help="print only the plan JSON (schema fleetctl.plan/1)")
    plan.add_argument("--plot", metavar="OUT.png", help="draw the plan to a PNG file")
    plan.add_argument("--export", metavar="DIR",
                      help="also write DIR/<vehicle>.plan (QGroundControl) for every vehicle and "
                           "DIR/plan.geojson (see docs/formats.md)")
    plan.set_defaults(func=cmd_plan)
    _add_fly_commands(sub)
    _add_controller_commands(sub)
    _add_watch_command(sub)
    _add_replay_command(sub)
    _add_keys_command(sub)
    return p


# ---------------------------------------------------------------------------------------------------
# status and sim: preflight against live (or simulated) vehicles, and serving the simulated fleet
# ---------------------------------------------------------------------------------------------------

EXIT_NOT_READY = 1


def _add_controller_commands(sub: argparse._SubParsersAction) -> None:
    status = sub.add_parser(
        "status", help="preflight: connect to every vehicle of the mission and show its state",
        description="Connect to the carrier and every rover the mission names (starting the embedded "
                    "simulated fleet for 'connection: sim') and show one row each: link, autopilot, "
                    "armed, mode, battery, position and whether a rover sits on the carrier's deck. "
                    "Exit status 1 when a vehicle does not answer or is not ready.",
    )
    status.add_argument("--mission", "-m", required=True, help="mission YAML file (see missions/)")
    status.add_argument("--timeout", type=float, default=5.0,
                        help="seconds to wait for each vehicle's first heartbeat (default 5)")
    status.add_argument("--speedup", type=float, default=None,
                        help="simulated time factor for 'connection: sim' (default: the mission's)")
    status.add_argument("--json", action="store_true",
                        help="print one JSON object per vehicle and line, with every check, "
                             "instead of the table")
    status.set_defaults(func=cmd_status)

    sim = sub.add_parser(
        "sim", help="serve the mission's simulated fleet until Ctrl-C",
        description="Run the simulated carrier and rovers of the mission, speaking MAVLink 2 over UDP on "
                    "the mission's connection URLs ('sim' = free loopback ports), and print each "
                    "vehicle's URL as the controller uses it. Stops on Ctrl-C or SIGTERM.",
    )
    sim.add_argument("--mission", "-m", required=True, help="mission YAML file (see missions/)")
    sim.add_argument("--speedup", type=float, default=None,
                     help="simulated seconds per wall second (default: the mission's sim.speedup)")
    sim.set_defaults(func=cmd_sim)


def _check_speedup(speedup: float | None) -> None:
    if speedup is not None and not speedup > 0:
        raise CliError(f"--speedup must be > 0, got {speedup}")


@contextlib.asynccontextmanager
async def _embedded_fleet(mission: Mission, **options: Any) -> AsyncIterator[Any]:
    """The mission's embedded simulated fleet for the block (None on real links), as every flying
    command starts it (:func:`fleetctl.run.sim.embedded_fleet`: every carrier and rover of every
    team); its errors as a :class:`CliError`."""
    from fleetctl.run.context import ExecutionError
    from fleetctl.run.sim import embedded_fleet

    _check_speedup(options.get("speedup"))
    try:
        fleet = embedded_fleet(mission, **options)
        sim = await fleet.__aenter__()
    except ExecutionError as e:
        raise CliError(str(e)) from None
    try:
        yield sim
    finally:
        await fleet.__aexit__(None, None, None)


def cmd_sim(args: argparse.Namespace) -> int:
    import asyncio
    import signal

    mission = load_mission(args.mission)

    async def serve() -> None:
        async with _embedded_fleet(mission, speedup=args.speedup, always=True) as fleet:
            print(f"simulated fleet {mission.name!r} running at {fleet.speedup:g}x; "
                  "controller-side URLs (Ctrl-C to stop):")
            sysids = {s.id: s.sysid for s in fleet.config.vehicles}
            for vid, url in fleet.endpoints.items():
                print(f"  {vid:<12} sysid {sysids[vid]:<4} {url}")
            sys.stdout.flush()
            stop = asyncio.Event()
            loop = asyncio.get_running_loop()
            for sig in (signal.SIGTERM, signal.SIGINT):
                loop.add_signal_handler(sig, stop.set)
            await stop.wait()  # until Ctrl-C / SIGTERM

    with contextlib.suppress(KeyboardInterrupt):
        asyncio.run(serve())
    print("simulated fleet stopped")
    return 0


def cmd_status(args: argparse.Namespace) -> int:
    import asyncio

    mission = load_mission(args.mission)
    if not args.timeout > 0:
        raise CliError(f"--timeout must be > 0, got {args.timeout}")
    return asyncio.run(_status(mission, args.timeout, args.speedup, args.json))


async def _status(mission: Mission, timeout: float, speedup: float | None, as_json: bool = False) -> int:
    from fleetctl.mavlink.fleet import connect_fleet
    from fleetctl.mavlink.link import LinkError
    from fleetctl.run.preflight import check_connected
    from fleetctl.run.safety import gather
    from fleetctl.views import status as view

    async with _embedded_fleet(mission, speedup=speedup) as sim:
        endpoints = sim.endpoints if sim is not None else None
        try:
            fleet = await connect_fleet(mission, endpoints, timeout=timeout, require_all=False)
        except LinkError as e:
            raise CliError(str(e)) from None
        try:
            failsafe = await gather(fleet, min(timeout, 3.0))  # preflight telemetry, link-loss parameters
            rows = check_connected(fleet, mission)  # the checks every flying command runs
            for vid, fs in failsafe.items():
                rows[vid].link_loss = fs.text
            _rtl_warnings(fleet.carrier_ids, rows, failsafe)
            if as_json:
                view.print_json(view.json_objects(mission, fleet, rows))
            else:
                view.print_table(mission, view.status_rows(mission, fleet, rows))
        finally:
            await fleet.close()
    notes = sys.stderr if as_json else sys.stdout
    for vid, pre in rows.items():
        for w in pre.warnings:
            print(f"warning: {vid}: {w}", file=notes)
    report = view.not_ready_report(fleet, rows)
    if report:
        for line in report:
            print(line, file=sys.stderr)
        return EXIT_NOT_READY
    print(f"all {len(rows)} vehicles connected and ready", file=notes)
    return 0


def _rtl_warnings(carriers: tuple[str, ...], rows: dict[str, Any], failsafe: dict[str, Any]) -> None:
    from fleetctl.run.safety import RTL_WARNING

    for vid, fs in failsafe.items():
        if vid not in carriers and fs.action is not None and "rtl" in fs.action.lower():
            rows[vid].warnings.append(f"link loss {fs.text.removeprefix('link loss: ')}: {RTL_WARNING}")


# ---------------------------------------------------------------------------------------------------
# the MQTT fleet bus: --mqtt/--topic-prefix on deploy/collect/run, and fleetctl watch
# ---------------------------------------------------------------------------------------------------


def _add_bus_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--mqtt", metavar="URL",
                   help="publish status, plan, telemetry and events to this MQTT broker and take task "
                        "changes from it (mqtt://HOST[:PORT] or mqtts://HOST[:PORT]; default: the "
                        "mission's mqtt: section; off when neither)")
    p.add_argument("--topic-prefix", metavar="P",
                   help="MQTT topic prefix (default: the mission's mqtt.topic_prefix, "
                        "else fleetctl/<mission name>)")


def _bus_config(mission: Mission, args: argparse.Namespace) -> object:
    from fleetctl.bus.config import BusConfigError, bus_config

    if getattr(args, "topic_prefix", None) and not (args.mqtt or mission.mqtt):
        raise CliError("--topic-prefix needs --mqtt URL (or an mqtt: section in the mission)")
    try:
        return bus_config(mission, getattr(args, "mqtt", None), getattr(args, "topic_prefix", None))
    except BusConfigError as e:
        raise CliError(str(e)) from None


def _add_watch_command(sub: argparse._SubParsersAction) -> None:
    w = sub.add_parser(
        "watch", help="the live view of a mission flown elsewhere, from the MQTT bus",
        description="Subscribe to a controller's MQTT fleet bus (status, plan, telemetry, events under "
                    "the topic prefix) and show the live view, or with --headless print its events and, "
                    "at the end, the fleet table. Ctrl-C stops it (exit status 0).",
    )
    w.add_argument("--mqtt", required=True, metavar="URL", help="broker: mqtt://HOST[:PORT] or mqtts://HOST[:PORT]")
    w.add_argument("--topic-prefix", required=True, metavar="P", help="the controller's topic prefix")
    w.add_argument("--headless", action="store_true", help="print events instead of the live view")
    w.add_argument("--exit-on-done", action="store_true",
                   help="exit when the controller's status goes done/failed/interrupted/offline")
    w.add_argument("--username", help="broker user name")
    w.add_argument("--password-env", metavar="VAR", help="environment variable holding the broker password")
    w.add_argument("--tls-ca", metavar="FILE", help="CA certificate(s) to verify the broker (implies TLS)")
    w.add_argument("--tls-cert", metavar="FILE", help="client certificate (implies TLS)")
    w.add_argument("--tls-key", metavar="FILE", help="client private key")
    _add_view_options(w)
    w.set_defaults(func=cmd_watch)


def cmd_watch(args: argparse.Namespace) -> int:
    import asyncio
    import os

    from fleetctl.bus.config import BusConfig, BusConfigError, Secret, parse_url
    from fleetctl.views.watch import watch

    try:
        host, port, tls = parse_url(args.mqtt)
    except BusConfigError as e:
        raise CliError(str(e)) from None
    password = None
    if args.password_env:
        password = os.environ.get(args.password_env)
        if password is None:
            raise CliError(f"--password-env: the environment variable {args.password_env} is not set")
    prefix = args.topic_prefix.strip("/")
    if not prefix or any(c in prefix for c in "+#"):
        raise CliError(f"--topic-prefix {args.topic_prefix!r}: give the controller's prefix, without + or #")
    config = BusConfig(host, port, prefix, tls or bool(args.tls_ca or args.tls_cert), None, args.username,
                       Secret(password) if password is not None else None, args.tls_ca, args.tls_cert,
                       args.tls_key)
    try:
        headless = args.headless or not sys.stdout.isatty()
        return asyncio.run(watch(config, headless=headless, exit_on_done=args.exit_on_done,
                                 latlon=args.latlon, extra_view=_web_view(args, None, headless)))
    except BusConfigError as e:
        raise CliError(str(e)) from None
    except KeyboardInterrupt:
        return 0


# ---------------------------------------------------------------------------------------------------
# keys: MAVLink 2 signing set-up (docs/signing.md)
# ---------------------------------------------------------------------------------------------------


def _add_keys_command(sub: argparse._SubParsersAction) -> None:
    keys = sub.add_parser("keys", help="MAVLink 2 signing keys (see docs/signing.md)",
                          description="Manage the fleet's MAVLink 2 signing key (links.signing).")
    ksub = keys.add_subparsers(dest="keys_command", metavar="ACTION")
    ksub.required = True
    prov = ksub.add_parser(
        "provision", help="send the mission's signing key to every vehicle (SETUP_SIGNING)",
        description="Connect to every vehicle of the mission, send it the key from the environment "
                    "variable named by links.signing.key_env (SETUP_SIGNING; an armed vehicle is refused) "
                    "and check that it then answers signed traffic. One line per vehicle; exit status 1 "
                    "when any failed. SETUP_SIGNING carries the key in clear: provision over a trusted link.",
    )
    prov.add_argument("--mission", "-m", required=True, help="mission YAML file with links.signing")
    prov.add_argument("--timeout", type=float, default=5.0,
                      help="seconds to wait for each vehicle's heartbeat (default 5)")
    prov.set_defaults(func=cmd_keys_provision)


def cmd_keys_provision(args: argparse.Namespace) -> int:
    import asyncio

    from fleetctl.mavlink.signing import SigningKey, SigningKeyError

    mission = load_mission(args.mission)
    if not args.timeout > 0:
        raise CliError(f"--timeout must be > 0, got {args.timeout}")
    if mission.links.signing is None:
        raise CliError(f"{mission.path or mission.name}: no links.signing section; add "
                       "links: {signing: {key_env: VAR}} and export the key in VAR (docs/signing.md)")
    try:
        key = SigningKey.from_env(mission.links.signing.key_env)
    except SigningKeyError as e:
        raise CliError(str(e)) from None
    return asyncio.run(_keys_provision(mission, key, args.timeout))


async def _keys_provision(mission: Mission, key: object, timeout: float) -> int:
    from fleetctl.mavlink.fleet import fleet_urls
    from fleetctl.mavlink.link import LinkError
    from fleetctl.mavlink.provision import provision
    from fleetctl.mavlink.signing import SigningKey

    assert isinstance(key, SigningKey)
    async with _embedded_fleet(mission, signing_from_env=False) as sim:  # it starts without a key
        try:
            urls = fleet_urls(mission, sim.endpoints if sim is not None else None)
        except LinkError as e:
            raise CliError(str(e)) from None
        results = await provision(mission, key, urls, timeout=timeout)
    for r in results:
        print(r.line())
    failed = [r for r in results if not r.ok]
    if failed:
        print(f"fleetctl: {len(failed)} of {len(results)} vehicle(s) not provisioned", file=sys.stderr)
        return 1
    print(f"all {len(results)} vehicles sign with key {key.fingerprint}")
    return 0


# ---------------------------------------------------------------------------------------------------
# the views: --web HOST:PORT (live map), --tiles, --latlon; fleetctl replay (docs/web-map.md)
# ---------------------------------------------------------------------------------------------------


def _add_view_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--web", metavar="HOST:PORT",
                   help="also serve a live map page there (e.g. 127.0.0.1:8080; 0.0.0.0:PORT lets other "
                        "machines see it, with a token: the link printed at start, or "
                        "FLEETCTL_WEB_TOKEN); self-contained, no internet needed")
    p.add_argument("--tiles", metavar="URL",
                   help="with --web: draw map tiles under the map from this XYZ template, e.g. "
                        "http://tiles.local/{z}/{x}/{y}.png (default: none)")
    p.add_argument("--latlon", action="store_true",
                   help="terminal view: latitude/longitude instead of E/N metres")


def _web_view(args: argparse.Namespace, origin: object, headless: bool) -> Any:
    """The web map view of ``--web`` (None without it); refuses a bad address, a bad
    FLEETCTL_WEB_TOKEN or --tiles alone. Bound beyond loopback the map has a token: its link is
    printed once (``web map: http://HOST:PORT/?token=...``: with --headless when the map listens,
    else before the live view starts); a token from the environment is not printed."""
    if getattr(args, "tiles", None) and not args.web:
        raise CliError("--tiles needs --web HOST:PORT")
    if not getattr(args, "web", None):
        return None
    from fleetctl.views.web import TOKEN_ENV, WebError, WebMapView, map_token, parse_address

    try:
        host, port = parse_address(args.web)
        token, from_env = map_token(host)
    except WebError as e:
        raise CliError(str(e)) from None
    if args.tiles and origin is None:
        raise CliError("--tiles needs the mission origin: watch has no mission file (use replay or the "
                       "flying commands)")

    def line(link: str) -> str:
        if token is None:
            return f"web map: {link}"
        url = link.split("?", 1)[0]
        if from_env:
            return f"web map: {url}?token=${TOKEN_ENV} (the token in {TOKEN_ENV}: bound beyond loopback)"
        return f"web map: {link} (the token is required: bound beyond loopback; {TOKEN_ENV} sets your own)"

    def ready(link: str) -> None:
        if headless:
            print(line(link), flush=True)

    if not headless and token is not None and port != 0:  # once, before the live view takes the terminal
        shown = f"[{host}]" if ":" in host else host
        print(line(f"http://{shown}:{port}/?token={token}"), flush=True)
    return WebMapView(host, port, origin=origin, tiles=args.tiles, on_ready=ready,  # type: ignore[arg-type]
                      token=token)


def _with_web(args: argparse.Namespace, view: Any, origin: object) -> Any:
    """``view`` plus the web map of ``--web`` (its address shown as a status line of the live view)."""
    from fleetctl.views.dashboard import HeadlessView
    from fleetctl.views.view import Views
    from fleetctl.views.web import parse_address

    web = _web_view(args, origin, isinstance(view, HeadlessView))
    if web is None:
        return view
    any_port = parse_address(args.web)[1] == 0  # chosen when it listens: its link was not printed
    if hasattr(view, "add_status"):
        def line() -> str:
            server = web.server
            if web.error or server.token is None:
                return f"web map: {web.error or server.url}"
            if any_port:
                return f"web map: {server.link}"
            return f"web map: {server.url} (token required: its link was printed at start)"

        view.add_status(line)
    return Views(view, web)


def _add_replay_command(sub: argparse._SubParsersAction) -> None:
    r = sub.add_parser(
        "replay", help="play a run's records back into the terminal view (and the web map)",
        description="Play RUN_DIR's journal, plan and MAVLink log (traffic.tlog) back in mission time: "
                    "the vehicles' states and positions as they were, into the terminal view and, with "
                    "--web, the map. Exit status 2 for a missing or unreadable run folder.",
    )
    r.add_argument("run_dir", metavar="RUN_DIR", help="a run folder (runs/<mission>-<timestamp>)")
    r.add_argument("--speed", type=float, default=1.0, metavar="X",
                   help="mission seconds per wall second (default 1; 0 = as fast as possible)")
    r.add_argument("--instant", action="store_true", help="as fast as possible (like --speed 0)")
    r.add_argument("--headless", action="store_true", help="print the events instead of the live view")
    r.add_argument("--linger", type=float, default=0.0, metavar="S",
                   help="with --web: keep serving the final state S wall seconds after the end")
    _add_view_options(r)
    r.set_defaults(func=cmd_replay)


def cmd_replay(args: argparse.Namespace) -> int:
    import asyncio

    from fleetctl.views.dashboard import make_view
    from fleetctl.views.replay import ReplayError, load_run, replay

    if args.speed < 0 or args.linger < 0:
        raise CliError("--speed and --linger must be >= 0")
    try:
        run = load_run(args.run_dir)
    except ReplayError as e:
        raise CliError(str(e)) from None
    headless = args.headless or not sys.stdout.isatty()
    view = _with_web(args, make_view(headless, latlon=args.latlon), run.origin)
    speed = 0.0 if args.instant else args.speed
    try:
        state = asyncio.run(replay(run, view, speed=speed, linger=args.linger))
    except KeyboardInterrupt:
        return 130
    if headless:
        from fleetctl.views.dashboard import render_text

        print(render_text(state, latlon=args.latlon), end="", flush=True)
    return 0


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
    except BrokenPipeError:  # `fleetctl plan --json | head`: the reader left, no traceback
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141


if __name__ == "__main__":
    sys.exit(main())
