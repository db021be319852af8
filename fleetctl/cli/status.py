"""``fleetctl status``: connect to every vehicle of the mission (the embedded simulated fleet for
``connection: sim``), run the preflight (:func:`fleetctl.run.safety.status_preflight`) and show it
(:mod:`fleetctl.views.status`)."""

from __future__ import annotations

import argparse
import asyncio
import sys

from fleetctl.cli.embedded import embedded_fleet
from fleetctl.cli.errors import EXIT_NOT_READY, CliError, check_timeout
from fleetctl.mavlink.fleet import connect_fleet
from fleetctl.mavlink.link import LinkError
from fleetctl.mission import Mission, load_mission
from fleetctl.run.preflight import PreflightRow
from fleetctl.run.safety import status_preflight
from fleetctl.views import status as view


def cmd_status(args: argparse.Namespace) -> int:
    mission = load_mission(args.mission)
    check_timeout(args.timeout)
    return asyncio.run(_status(mission, args.timeout, args.speedup, args.json))


async def _status(mission: Mission, timeout: float, speedup: float | None, as_json: bool) -> int:
    async with embedded_fleet(mission, speedup=speedup) as sim:
        endpoints = sim.endpoints if sim is not None else None
        try:
            fleet = await connect_fleet(mission, endpoints, timeout=timeout, require_all=False)
        except LinkError as e:
            raise CliError(str(e)) from None
        try:
            rows = await status_preflight(fleet, mission, timeout)
            if as_json:
                view.print_json(view.json_objects(mission, fleet, rows))
            else:
                view.print_table(mission, view.status_rows(mission, fleet, rows))
        finally:
            await fleet.close()
    report = view.not_ready_report(fleet, rows)
    _print_verdict(rows, report, as_json)
    return EXIT_NOT_READY if report else 0


def _print_verdict(rows: dict[str, PreflightRow], report: list[str], as_json: bool) -> None:
    notes = sys.stderr if as_json else sys.stdout
    for vid, pre in rows.items():
        for w in pre.warnings:
            print(f"warning: {vid}: {w}", file=notes)
    for line in report:
        print(line, file=sys.stderr)
    if not report:
        print(f"all {len(rows)} vehicles connected and ready", file=notes)
