"""``fleetctl watch``: the live view of a mission flown elsewhere, from its controller's MQTT bus
(:func:`fleetctl.views.watch.watch`)."""

from __future__ import annotations

import argparse
import asyncio
import os
import sys

from fleetctl.bus.config import BusConfig, BusConfigError, Secret, parse_url
from fleetctl.cli.errors import CliError
from fleetctl.cli.web import web_view
from fleetctl.views.watch import watch


def cmd_watch(args: argparse.Namespace) -> int:
    config = _watch_config(args)
    try:
        headless = args.headless or not sys.stdout.isatty()
        return asyncio.run(watch(config, headless=headless, exit_on_done=args.exit_on_done,
                                 latlon=args.latlon, extra_view=web_view(args, None, headless)))
    except BusConfigError as e:
        raise CliError(str(e)) from None
    except KeyboardInterrupt:
        return 0


def _watch_config(args: argparse.Namespace) -> BusConfig:
    """The broker and topic prefix of ``--mqtt``, ``--topic-prefix``, the user, password and TLS options."""
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
    return BusConfig(host, port, prefix, tls or bool(args.tls_ca or args.tls_cert), None, args.username,
                     Secret(password) if password is not None else None, args.tls_ca, args.tls_cert,
                     args.tls_key)
