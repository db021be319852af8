"""fleetctl.mavlink.tlog: the traffic of a link, written as a .tlog and read back with pymavlink."""

from __future__ import annotations

import os
import time
from pathlib import Path

from fleetctl.mavlink.link import Link
from fleetctl.mavlink.tlog import TlogWriter
from sitl import SimFleet


async def test_tlog_of_a_link_is_readable_by_pymavlink(sim: SimFleet, tmp_path: Path) -> None:
    path = tmp_path / "run" / "traffic.tlog"
    writer = TlogWriter(path, flush_interval=0.1)
    writer.start()
    t0 = time.time()
    async with Link(sim.endpoints["carrier"]) as link:
        link.add_tap(writer)
        await link.expect("HEARTBEAT", sysid=11)
        await link.command(11, 511, (33, 2e5))  # SET_MESSAGE_INTERVAL GLOBAL_POSITION_INT
        for _ in range(3):
            await link.expect("GLOBAL_POSITION_INT", sysid=11)
    await writer.aclose()
    t1 = time.time()
    assert writer.records > 5

    os.environ["MAVLINK20"] = "1"
    from pymavlink import mavutil

    log = mavutil.mavlink_connection(str(path), dialect="ardupilotmega")
    msgs = []
    while (m := log.recv_match()) is not None:
        msgs.append(m)
    assert len([m for m in msgs if m.get_type() != "BAD_DATA"]) == writer.records
    types = {(m.get_type(), m.get_srcSystem()) for m in msgs}
    assert ("HEARTBEAT", 255) in types  # ours, outgoing
    assert ("HEARTBEAT", 11) in types and ("COMMAND_ACK", 11) in types and ("COMMAND_LONG", 255) in types
    stamps = [m._timestamp for m in msgs]
    assert stamps == sorted(stamps) and t0 - 1 <= stamps[0] and stamps[-1] <= t1 + 1
