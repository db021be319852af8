"""The ``fleetctl`` argument parser: every command's options and ``--help`` (docs/cli.md).

Parsing only: the parser names the command (``args.command``) and :func:`fleetctl.cli.main`
imports the module that runs it.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import Any

from fleetctl import package_version
from fleetctl.cli.fly_parser import add_fly_commands
from fleetctl.cli.options import add_budget_option, add_view_options


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
    add_budget_option(plan)
    plan.add_argument("--json", action="store_true", help="print only the plan JSON (schema fleetctl.plan/1)")
    plan.add_argument("--plot", metavar="OUT.png", help="draw the plan to a PNG file")
    plan.add_argument("--export", metavar="DIR",
                      help="also write DIR/<vehicle>.plan (QGroundControl) for every vehicle and "
                           "DIR/plan.geojson (see docs/formats.md)")
    add_fly_commands(sub)
    _add_controller_commands(sub)
    _add_watch_command(sub)
    _add_replay_command(sub)
    _add_keys_command(sub)
    return p


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

    sim = sub.add_parser(
        "sim", help="serve the mission's simulated fleet until Ctrl-C",
        description="Run the simulated carrier and rovers of the mission, speaking MAVLink 2 over UDP on "
                    "the mission's connection URLs ('sim' = free loopback ports), and print each "
                    "vehicle's URL as the controller uses it. Stops on Ctrl-C or SIGTERM.",
    )
    sim.add_argument("--mission", "-m", required=True, help="mission YAML file (see missions/)")
    sim.add_argument("--speedup", type=float, default=None,
                     help="simulated seconds per wall second (default: the mission's sim.speedup)")


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
    add_view_options(w)


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
    add_view_options(r)
