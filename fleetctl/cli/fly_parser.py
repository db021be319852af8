"""The flying commands' arguments: ``deploy``, ``collect``, ``run`` and ``resume``."""

from __future__ import annotations

import argparse

from fleetctl.cli.options import add_budget_option, add_bus_options, add_view_options

_FLY_EPILOG = """\
connection: sim starts the embedded simulated fleet in this process (at the mission's sim.speedup,
or --speedup). Its rovers start on the carrier's deck, so 'collect' on a sim mission first places
the rovers named in the mission's 'collection:' section at their positions there (with the battery
their 'range' implies; the others stay on the deck) and refuses a mission without that section -
fly 'run' to deploy, dwell and collect in one go.

Records: runs/<mission>-<timestamp>/ (or --run-dir DIR, named on the first output line) holds
journal.jsonl (written ahead of every command), traffic.tlog (all MAVLink traffic;
traffic-<id>.tlog for each further link), mission.yaml (a copy of the mission), plan.json,
export/ (the plan as QGroundControl .plan files and GeoJSON)
and summary.json (schema fleetctl.summary/1; also --summary).
Exit status: 0 mission complete, 1 not complete (or a vehicle did not answer, an upload was
rejected), 2 bad mission file or option, 130 interrupted by Ctrl-C, 143 by SIGTERM (airborne
rovers were told to hold; 'fleetctl resume --run DIR' finishes the run).
"""


def add_fly_commands(sub: argparse._SubParsersAction) -> None:
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
    add_resume_command(sub)



def _add_shared_fly_options(p: argparse.ArgumentParser) -> None:
    add_budget_option(p)
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
    add_bus_options(p)
    add_view_options(p)


_RESUME_EPILOG = """\
What it does: reads DIR/journal.jsonl (written ahead of every command, so it says what was
commanded up to the crash) and DIR/mission.yaml, reconnects to the live fleet, checks the journal
against telemetry (rovers on the deck, flying to their task, holding on it, landed elsewhere,
lost; where the carrier is), then finishes the interrupted phase - and for a 'run' the dwell and
the collection - with the same planners and replanning. It never launches a rover that is flying
and never serves a reached task again; it appends to the same journal (a 'resumed' record) and
writes DIR/summary.json for the whole run. A long operation (operation: true) is replanned from
the live state: work done is not done again, rovers in the air go on with their sorties
(docs/operations.md#resuming-an-operation).

Several teams (carriers:) in one controller: each team's deployment goes on from its own journal
(DIR/teams/<carrier>/deploy/) over the tasks it owns now (its share and the hand-overs recorded in
DIR/journal.jsonl), then the dwell left, then the collection shared out again from the live fleet.
The run folder of a --team controller is resumed as that team's run (re-joining the bus with its
claims). docs/teams.md#resume says more.

It refuses (exit 2) a folder without a journal, a run that completed, a --mission that is not
the saved one, and a run on the embedded simulated fleet (connection: sim), which died with the
controller. Exit status otherwise as for deploy/collect/run.
"""


def add_resume_command(sub: argparse._SubParsersAction) -> None:
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

