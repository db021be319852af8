"""The ``fleetctl`` command line (docs/cli.md): :func:`main` parses the arguments
(:mod:`.parser`), imports the module of the command given and calls it.

Each command module parses nothing itself: it checks the options, calls the domain modules
(``fleetctl.run``, ``fleetctl.mission``, ``fleetctl.views``, ``fleetctl.mavlink``, ``planners``) and
prints. The command modules are the lazy imports of the command line, in one place
(:data:`COMMAND_MODULES`): ``fleetctl --help`` and a usage error load argparse and this package
only, and a command loads what it needs (NumPy, asyncio, MAVLink, rich, aiohttp...) when it runs.
"""

from __future__ import annotations

import importlib
import logging
import os
import sys
from collections.abc import Callable, Sequence
from typing import cast

from fleetctl.cli.errors import EXIT_BROKEN_PIPE, EXIT_USAGE, CliError
from fleetctl.cli.parser import build_parser

# command -> (module of fleetctl.cli, function): imported only when the command runs
COMMAND_MODULES: dict[str, tuple[str, str]] = {
    "plan": ("plan", "cmd_plan"),
    "deploy": ("fly", "cmd_fly"),
    "collect": ("fly", "cmd_fly"),
    "run": ("fly", "cmd_fly"),
    "resume": ("fly", "cmd_resume"),
    "status": ("status", "cmd_status"),
    "sim": ("sim", "cmd_sim"),
    "watch": ("watch", "cmd_watch"),
    "replay": ("replay", "cmd_replay"),
    "keys": ("keys", "cmd_keys"),
}

Command = Callable[..., int]


def command_function(command: str) -> Command:
    """The function that runs ``command`` (its module imported now)."""
    module, name = COMMAND_MODULES[command]
    return cast(Command, getattr(importlib.import_module(f"fleetctl.cli.{module}"), name))


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    try:
        run = command_function(args.command)
        from fleetctl.mission import MissionError  # loaded by every command module: no cost here

        try:
            return int(run(args) or 0)
        except MissionError as e:
            raise CliError(str(e)) from None
    except CliError as e:
        print(f"fleetctl: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("fleetctl: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # `fleetctl plan --json | head`: the reader left, no traceback
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE


__all__ = ["COMMAND_MODULES", "CliError", "build_parser", "command_function", "main"]
