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


async def test_tlog_of_connect_fleet_records_the_connect_phase(sim: SimFleet, tmp_path: Path) -> None:
    """The tap is on the links before they open: the first heartbeats, the SET_MESSAGE_INTERVAL
    requests and their acks are in the .tlog (the run's records used to start after connect)."""
    from fleetctl.mavlink.fleet import connect_fleet
    from tests.run.ctl_helpers import mission_dict, mission_from

    path = tmp_path / "traffic.tlog"
    writer = TlogWriter(path, flush_interval=0.1)
    writer.start()
    mission = mission_from(mission_dict(), tmp_path)
    async with await connect_fleet(mission, sim.endpoints, timeout=5.0, tap=writer):
        pass  # connect only: first heartbeats, then the message rates of every vehicle
    await writer.aclose()

    os.environ["MAVLINK20"] = "1"
    from pymavlink import mavutil

    log = mavutil.mavlink_connection(str(path), dialect="ardupilotmega")
    msgs = []
    while (m := log.recv_match()) is not None:
        msgs.append(m)
    first_hb = {m.get_srcSystem() for m in msgs if m.get_type() == "HEARTBEAT"}
    assert {1, 11, 12} <= first_hb
    intervals = [m for m in msgs if m.get_type() == "COMMAND_LONG" and m.command == 511]
    assert {m.target_system for m in intervals} >= {1, 11, 12}
    acks = [m for m in msgs if m.get_type() == "COMMAND_ACK" and m.command == 511]
    assert {m.get_srcSystem() for m in acks} >= {1, 11, 12}


def test_read_telemetry_gives_the_autopilots_positions_and_batteries(tmp_path: Path) -> None:
    """Positions and batteries of component 1 come back in order with their log times and units;
    another component's messages and other message types are left out; -1 % is unknown."""
    import pytest
    from pymavlink.dialects.v20 import ardupilotmega as M

    from fleetctl.mavlink.tlog import TlogBattery, TlogPosition, read_telemetry, tlog_record

    def packed(msg: object, sysid: int, compid: int) -> bytes:
        return msg.pack(M.MAVLink(None, srcSystem=sysid, srcComponent=compid))  # type: ignore[attr-defined]

    pos = M.MAVLink_global_position_int_message(0, 473977420, 85455940, 498000, 10000, 300, 400, 0, 0)
    bat = M.MAVLink_battery_status_message(0, 0, 0, 2500, [0] * 10, 0, 0, 0, -1)
    path = tmp_path / "t.tlog"
    path.write_bytes(tlog_record(100.0, packed(pos, 11, 1)) + tlog_record(100.5, packed(pos, 12, 190))
                     + tlog_record(101.0, packed(M.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3), 11, 1))
                     + tlog_record(101.5, packed(bat, 11, 1)))
    got = list(read_telemetry(path))
    assert len(got) == 2 and isinstance(got[0], TlogPosition) and isinstance(got[1], TlogBattery)
    p = got[0]
    assert (p.sysid, p.t) == (11, pytest.approx(100.0)) and p.lat == pytest.approx(47.397742)
    assert (p.alt, p.relative_alt, p.speed) == (pytest.approx(498.0), pytest.approx(10.0), pytest.approx(5.0))
    assert got[1].sysid == 11 and got[1].pct is None
