"""``fleetctl keys provision``: MAVLink 2 signing set-up (docs/signing.md) - send the mission's key
to every vehicle and check that it then answers signed traffic."""

from __future__ import annotations

import argparse
import asyncio
import sys

from fleetctl.cli.embedded import embedded_fleet
from fleetctl.cli.errors import CliError, check_timeout
from fleetctl.mavlink.fleet import fleet_urls
from fleetctl.mavlink.link import LinkError
from fleetctl.mavlink.provision import provision
from fleetctl.mavlink.signing import SigningKey, SigningKeyError
from fleetctl.mission import Mission, load_mission


def cmd_keys(args: argparse.Namespace) -> int:
    """``keys ACTION`` (``provision``, the one action so far)."""
    mission = load_mission(args.mission)
    check_timeout(args.timeout)
    if mission.links.signing is None:
        raise CliError(f"{mission.path or mission.name}: no links.signing section; add "
                       "links: {signing: {key_env: VAR}} and export the key in VAR (docs/signing.md)")
    try:
        key = SigningKey.from_env(mission.links.signing.key_env)
    except SigningKeyError as e:
        raise CliError(str(e)) from None
    return asyncio.run(_provision(mission, key, args.timeout))


async def _provision(mission: Mission, key: SigningKey, timeout: float) -> int:
    async with embedded_fleet(mission, signing_from_env=False) as sim:  # it starts without a key
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
