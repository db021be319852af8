"""Parameters on a lossy link (fleetctl.mavlink.params): a read is resent after the link's
retransmission timeout for the whole patience, so a 40 % lossy link still answers every read (three
fixed one-second attempts left one read in four unanswered)."""

from __future__ import annotations

import asyncio

from fleetctl.mavlink.fleet import Fleet
from fleetctl.mavlink.params import read_param
from fleetctl.mavlink.vehicle import Vehicle
from sitl import SimFleet


async def test_every_read_is_answered_on_a_40_percent_lossy_link(sim: SimFleet, fleet: Fleet) -> None:
    rovers = list(fleet.rovers.values())
    for v in rovers:  # round trips measured on the clean link
        await v.request_message(0, timeout=1.0)
    sim.set_packet_loss(0.4)

    async def reads(v: Vehicle) -> list[tuple[float, int] | None]:
        return [await read_param(v, "NAV_DLL_ACT") for _ in range(10)]  # one at a time

    got = [g for per in await asyncio.gather(*(reads(v) for v in rovers)) for g in per]
    assert len(got) == 20 and all(g is not None for g in got), got
    assert sum(sim.link_stats(v.name)["rx_lost"] for v in rovers) > 0
