"""``fleetctl replay RUN_DIR``: play a run's records back in mission time into the terminal view
and, with ``--web``, the map (docs/web-map.md)."""

from __future__ import annotations

import argparse
import asyncio
import sys

from fleetctl.cli.errors import CliError
from fleetctl.cli.web import with_web
from fleetctl.views.dashboard import make_view, render_text
from fleetctl.views.replay import ReplayError, load_run, replay


def cmd_replay(args: argparse.Namespace) -> int:
    if args.speed < 0 or args.linger < 0:
        raise CliError("--speed and --linger must be >= 0")
    try:
        run = load_run(args.run_dir)
    except ReplayError as e:
        raise CliError(str(e)) from None
    headless = args.headless or not sys.stdout.isatty()
    view = with_web(args, make_view(headless, latlon=args.latlon), run.origin)
    speed = 0.0 if args.instant else args.speed
    try:
        state = asyncio.run(replay(run, view, speed=speed, linger=args.linger))
    except KeyboardInterrupt:
        return 130
    if headless:
        print(render_text(state, latlon=args.latlon), end="", flush=True)
    return 0
