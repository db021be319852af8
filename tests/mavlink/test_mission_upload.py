"""The mission upload on a lossy link: its exchanges measure the link's round trips and a lost item
is resent after the link's retransmission timeout, not after a fixed quarter second; a
MAV_MISSION_INVALID_SEQUENCE answer to a resent item that crossed its request (as ArduPilot
answers a duplicate) does not fail the upload."""

from __future__ import annotations

import asyncio
import contextlib
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.mavlink.link import Link
from fleetctl.mavlink.mission_protocol import MISSION_ITEM_TIMEOUT
from fleetctl.mavlink.rtt import MIN_RTO
from sitl import SimFleet
from tests.mavlink.test_link import waypoints
from tests.run.ctl_helpers import free_udp_port


async def test_an_upload_measures_the_link_and_resends_at_its_timeout(sim: SimFleet) -> None:
    sim.set_packet_loss(0.4, vehicle="r2")
    items = waypoints(15)
    async with Link(sim.endpoints["carrier"]) as link:
        await link.expect("HEARTBEAT", sysid=12)
        assert link.rtt.samples == 0
        waits: list[float] = []
        timeout = link.rtt.timeout

        def spy(ceiling: float) -> float:
            waits.append(timeout(ceiling))
            return waits[-1]

        link.rtt.timeout = spy  # type: ignore[method-assign]
        await link.upload_mission(12, items)
        lost = sim.link_stats("r2")["rx_lost"] + sim.link_stats("r2")["tx_lost"]
        samples = link.rtt.samples
        known = waits[len(waits) // 2:]  # the first waits may come before a round trip is known
        # the read-back only checks the upload: at 40 % loss each way its 16 exchanges of 8 sends
        # each failed once in a fresh clone's run (about 4 % of runs)
        sim.set_packet_loss(0.0, vehicle="r2")
        back = await link.download_mission(12)
    assert all(a.same_as(b) for a, b in zip(items, back, strict=True)) and len(back) == 15
    assert samples > 0  # the transfer's own exchanges are round trips of the link
    assert known and all(MIN_RTO <= w < MISSION_ITEM_TIMEOUT for w in known), waits
    assert lost > 0


class _DuplicateRefuser(asyncio.DatagramProtocol):
    """A vehicle's side of the upload that answers an item it already has with
    MAV_MISSION_INVALID_SEQUENCE and then asks again for the one it needs; the first request for
    item 1 is not answered in time, so the controller resends item 0."""

    def __init__(self, count: int) -> None:
        self.mav = M.MAVLink(None, srcSystem=7, srcComponent=1)
        self.parser = M.MAVLink(None)
        self.count = count
        self.expected = 0
        self.received: list[int] = []
        self.refused = 0
        self.transport: Any = None

    def connection_made(self, transport: Any) -> None:
        self.transport = transport

    def send(self, msg: Any, addr: Any) -> None:
        self.transport.sendto(msg.pack(self.mav), addr)

    def datagram_received(self, data: bytes, addr: Any) -> None:
        for msg in self.parser.parse_buffer(data) or []:
            t = msg.get_type()
            if t == "MISSION_COUNT":
                self.send(self.mav.mission_request_int_encode(255, 190, 0, 0), addr)
            elif t == "MISSION_ITEM_INT" and msg.seq < self.expected:
                self.refused += 1
                self.send(self.mav.mission_ack_encode(255, 190, M.MAV_MISSION_INVALID_SEQUENCE, 0), addr)
                self.send(self.mav.mission_request_int_encode(255, 190, self.expected, 0), addr)
            elif t == "MISSION_ITEM_INT" and msg.seq == self.expected:
                self.received.append(msg.seq)
                self.expected += 1
                if self.expected == self.count:
                    self.send(self.mav.mission_ack_encode(255, 190, M.MAV_MISSION_ACCEPTED, 0), addr)
                elif self.expected > 1:
                    self.send(self.mav.mission_request_int_encode(255, 190, self.expected, 0), addr)
                # the request for item 1 is "lost": the controller resends item 0


async def test_an_invalid_sequence_answer_to_a_resent_item_is_passed_over() -> None:
    port = free_udp_port()
    peer = _DuplicateRefuser(4)
    loop = asyncio.get_running_loop()
    transport, _ = await loop.create_datagram_endpoint(lambda: peer, local_addr=("127.0.0.1", port))
    try:
        async with Link(f"udp://127.0.0.1:{port}", heartbeat_hz=0) as link:
            link.routes[7] = ("127.0.0.1", port)
            async with asyncio.timeout(10.0):
                await link.upload_mission(7, waypoints(4))
    finally:
        with contextlib.suppress(Exception):
            transport.close()
    assert peer.received == [0, 1, 2, 3]
    assert peer.refused >= 1  # item 0 came again, and was answered INVALID_SEQUENCE
