"""Messages with source system id 0 (PX4 sends some from every instance) are not a vehicle's:
no route, no subscriber, no route conflict."""

from __future__ import annotations

import asyncio
import socket
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.mavlink.link import Link


def _codec(sysid: int) -> Any:
    return M.MAVLink(None, srcSystem=sysid, srcComponent=1)


def _unknown_msgid(sysid: int, msgid: int = 290, seq: int = 0) -> bytes:
    """A MAVLink 2 frame with a message id outside the dialect (as PX4's sysid-0 messages are)."""
    import struct

    from pymavlink.generator.mavcrc import x25crc

    payload = b"\x01\x02\x03\x04"
    header = struct.pack("<BBBBBBBHB", 0xFD, len(payload), 0, 0, seq, sysid, 1, msgid & 0xFFFF, msgid >> 16)
    crc = x25crc(header[1:] + payload)
    return header + payload + struct.pack("<H", crc.crc)


async def test_system_id_0_is_not_a_vehicle_and_makes_no_route_conflict() -> None:
    async with Link("udpin://127.0.0.1:0") as link:
        port = link.local_port
        seen: list[int] = []
        conflicts: list[int] = []
        link.subscribe(lambda m: seen.append(m.get_srcSystem()))
        link.on_route_conflict = lambda sysid, old, new: conflicts.append(sysid)
        socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(3)]
        try:
            for i, s in enumerate(socks):  # three "vehicles", each also sending as system 0
                hb = _codec(11 + i).heartbeat_encode(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_PX4, 0, 0, 3)
                s.sendto(hb.pack(_codec(11 + i)), ("127.0.0.1", port))
                for k in range(3):
                    s.sendto(_unknown_msgid(0, seq=k), ("127.0.0.1", port))
                    st = _codec(0).sys_status_encode(0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0)
                    s.sendto(st.pack(_codec(0)), ("127.0.0.1", port))
            for _ in range(50):
                await asyncio.sleep(0.02)
                if link.rx_sysid0 >= 18 and len(seen) >= 3:
                    break
        finally:
            for s in socks:
                s.close()
        assert link.rx_sysid0 == 18
        assert link.route_conflicts == 0 and conflicts == []
        assert 0 not in link.routes and 0 not in link.last_heard
        assert sorted(seen) == [11, 12, 13]  # the vehicles' own messages still arrive
        assert sorted(link.routes) == [11, 12, 13]
