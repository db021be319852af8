"""``fleetctl deploy | collect | run`` and ``fleetctl resume``: check the options, build the
:class:`~fleetctl.run.lifecycle.RunOptions`, fly (:func:`fleetctl.run.flight.fly`, or
:func:`fleetctl.run.teams.own_controller.fly_team_controller` for ``--team ID``) and print the
outcome.

Imported when a flying command runs (it loads asyncio, MAVLink and the terminal view).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import dataclasses
import signal
import sys
from collections.abc import Callable

from fleetctl.bus.config import BusConfig, BusConfigError, bus_config
from fleetctl.cli.common import warn_mission
from fleetctl.cli.errors import EXIT_TERMINATED, CliError, check_speedup
from fleetctl.cli.web import with_web
from fleetctl.mission import Mission, MissionError, load_mission
from fleetctl.mission.teams import several_teams, team_mission
from fleetctl.run.context import ExecutionError
from fleetctl.run.flight import fly
from fleetctl.run.lifecycle import EXIT_INTERRUPTED, RunOptions, RunOutcome
from fleetctl.run.resume import ResumeError, load_resumption
from fleetctl.run.resume_teams import is_teams_run, load_teams_resumption
from fleetctl.run.sim import mission_uses_sim
from fleetctl.run.teams.own_controller import TeamSpec, fly_team_controller, prepare_team, team_bus_config
from fleetctl.run.teams.own_resume import own_team_resumption
from fleetctl.views.dashboard import make_view
from fleetctl.views.outcome import outcome_lines
from planners import PlanningError

Confirm = Callable[[list[str]], bool]


def cmd_fly(args: argparse.Namespace) -> int:
    mission = load_mission(args.mission)
    warn_mission(mission, args.command == "collect")
    if mission.operation and args.command != "run":
        raise CliError(f"{mission.path}: operation: a long operation is flown whole, its sorties "
                       f"deploying and collecting rovers in turn: fly it with "
                       f"'fleetctl run --mission {args.mission}' (docs/operations.md)")
    if args.command in ("deploy", "run") and not mission.tasks:
        raise CliError(f"{mission.path}: tasks: the mission has no tasks to deploy rovers to (a collection-"
                       f"only mission); fly it with 'fleetctl collect --mission {args.mission}'")
    return _fly(args, mission, args.command, RunOptions(run_dir=args.run_dir, runs_dir=args.runs))


def cmd_resume(args: argparse.Namespace) -> int:
    mission, command, where = _resumption(args)
    return _fly(args, mission, command, where)


def _resumption(args: argparse.Namespace) -> tuple[Mission, str, RunOptions]:
    """What ``resume --run DIR`` flies: the mission, the command and the run to finish; ``args``
    get the interrupted run's planner and dwell (unless given again) and, for a ``--team ID``
    controller's run, the team."""
    try:
        if is_teams_run(args.run):  # a run of several teams in one controller (docs/teams.md#resume)
            teams = load_teams_resumption(args.run, args.mission)
            _resumed_choices(args, teams.options)
            return teams.mission, teams.command, RunOptions(teams_resume=teams)
        own = own_team_resumption(args.run, args.mission, args.planner, args.dwell)
        resumption = own.resumption if own is not None else load_resumption(args.run, args.mission)
    except ResumeError as e:
        raise CliError(str(e)) from None
    if own is not None:  # a --team controller's run: that team again
        args.team, args.planner, args.dwell = own.team, own.planner, own.dwell
        return own.mission, resumption.command, RunOptions(resume=resumption)
    if several_teams(resumption.mission):
        raise CliError(f"{args.run}: the mission has {len(resumption.mission.teams)} carriers and the "
                       "journal's run record names neither its teams (every team in one controller) nor "
                       "the team it flew (--team ID); it cannot be told what to resume")
    _resumed_choices(args, resumption.options)
    return resumption.mission, resumption.command, RunOptions(resume=resumption)


def _resumed_choices(args: argparse.Namespace, options: dict[str, object]) -> None:
    """The interrupted run's planner and dwell, unless given again."""
    for key in ("planner", "dwell"):
        if getattr(args, key, None) is None:
            setattr(args, key, options.get(key))


def _fly(args: argparse.Namespace, mission: Mission, command: str, where: RunOptions) -> int:
    """Fly ``command``: ``where`` names the records (run folder, or what to resume)."""
    team = getattr(args, "team", None)
    check_speedup(args.speedup)
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
    opts = _run_options(args, mission, command, where, mqtt)
    try:
        outcome, terminated = asyncio.run(_with_sigterm(mission, command, opts, spec))
    except ExecutionError as e:  # raised before anything flew (e.g. collect on a sim mission)
        raise CliError(str(e)) from None
    lines = outcome_lines(command, mission, outcome)
    if outcome.error:
        print(f"fleetctl: error: {outcome.error}", file=sys.stderr)
    for line in lines:
        print(line, file=sys.stderr if outcome.exit_code else sys.stdout)
    if terminated and outcome.exit_code == EXIT_INTERRUPTED:
        return EXIT_TERMINATED
    return outcome.exit_code


def _run_options(args: argparse.Namespace, mission: Mission, command: str, where: RunOptions,
                 mqtt: BusConfig | None) -> RunOptions:
    view = with_web(args, make_view(True if args.headless else None, latlon=args.latlon), mission.origin)

    def announce(run_dir: object) -> None:
        print(f"run folder: {run_dir}", flush=True)

    real_clock = args.speedup is not None and mission.carrier.connection != "sim"  # SITL firmware run faster
    return dataclasses.replace(
        where, speedup=args.speedup, planner=args.planner, dwell=getattr(args, "dwell", None),
        summary_path=args.summary, view=view, connect_timeout=args.timeout, mqtt=mqtt, on_run_dir=announce,
        require_all=args.require_all, force=args.force, confirm=_arming_confirmation(args, mission, command),
        team=getattr(args, "team", None), clock_speedup=args.speedup if real_clock else None)


def _bus_config(mission: Mission, args: argparse.Namespace) -> BusConfig | None:
    if getattr(args, "topic_prefix", None) and not (args.mqtt or mission.mqtt):
        raise CliError("--topic-prefix needs --mqtt URL (or an mqtt: section in the mission)")
    try:
        return bus_config(mission, getattr(args, "mqtt", None), getattr(args, "topic_prefix", None))
    except BusConfigError as e:
        raise CliError(str(e)) from None


def _collecting_team(mission: Mission, team: str, mqtt: BusConfig | None) -> tuple[Mission, BusConfig | None]:
    """``collect --team ID``: the team's carrier collects the rovers of its deck (its own
    controller, its own bus prefix ``P/teams/ID``; nothing to coordinate)."""
    try:
        own = team_mission(mission, team, tasks=())
    except MissionError as e:
        raise CliError(str(e)) from None
    print(f"team {team}: collecting {', '.join(u.id for u in own.rovers.units)} with {team}", flush=True)
    return own, team_bus_config(mqtt, team)


def _team(mission: Mission, team: str, args: argparse.Namespace,
          mqtt: BusConfig | None) -> tuple[Mission, TeamSpec, BusConfig | None]:
    """``--team ID``: the team's own mission, the coordination spec, the team's bus settings."""
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


def _arming_confirmation(args: argparse.Namespace, mission: Mission, command: str) -> Confirm | None:
    """Real vehicles are armed only on a decision: asked on a terminal, or --yes."""
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


async def _with_sigterm(mission: Mission, command: str, opts: RunOptions,
                        spec: TeamSpec | None) -> tuple[RunOutcome, bool]:
    """Run the command; SIGTERM cancels it like Ctrl-C does (and is reported as such)."""
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
    try:
        if spec is not None:  # --team: one team of several (fleetctl.run.teams.own_controller)
            outcome = await fly_team_controller(mission, command, spec, opts)
        else:
            outcome = await fly(mission, command, opts)
    finally:
        with contextlib.suppress(NotImplementedError):  # (no handler was installed: see above)
            loop.remove_signal_handler(signal.SIGTERM)
    return outcome, bool(got)
