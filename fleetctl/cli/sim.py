"""``fleetctl sim``: serve the mission's simulated fleet on its connection URLs until Ctrl-C or
SIGTERM, for another ground station."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import signal
import sys

from fleetctl.cli.embedded import embedded_fleet
from fleetctl.mission import Mission, load_mission


def cmd_sim(args: argparse.Namespace) -> int:
    mission = load_mission(args.mission)
    with contextlib.suppress(KeyboardInterrupt):
        asyncio.run(_serve(mission, args.speedup))
    print("simulated fleet stopped")
    return 0


async def _serve(mission: Mission, speedup: float | None) -> None:
    async with embedded_fleet(mission, speedup=speedup, always=True) as fleet:
        assert fleet is not None  # always=True: whatever the connections say
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
