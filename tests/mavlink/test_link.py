"""fleetctl.mavlink.link against the simulated fleet over real UDP: URL modes, request/response,
command ACKs and retries, the mission protocol (round trip, loss, error ACK)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.mavlink.fleet import connect_fleet
from fleetctl.mavlink.link import Link, LinkError, LinkTimeout, MissionItem, MissionRejected, parse_url
from sitl import Fault, SimFleet
from tests.run.ctl_helpers import free_udp_port, mission_dict, mission_from, sim_fleet

LAT0, LON0 = 47.397742, 8.545594


def waypoints(n: int, z0: float = 5.0) -> list[MissionItem]:
    return [MissionItem(M.MAV_CMD_NAV_WAYPOINT, param1=0.5 * (i % 3), x=int(round((LAT0 + 1e-5 * i) * 1e7)),
                        y=int(round((LON0 + 2e-5 * i) * 1e7)), z=z0 + 0.25 * i) for i in range(n)]


def test_parse_url() -> None:
    assert parse_url("udpin://0.0.0.0:14550").kind == "udpin"
    assert parse_url("udp://10.0.0.2:14555").kind == "udpout"
    assert parse_url("udpout://10.0.0.2:14555").port == 14555
    a = parse_url("serial:///dev/ttyACM0?baud=921600")
    assert (a.kind, a.device, a.baud) == ("serial", "/dev/ttyACM0", 921600)
    with pytest.raises(LinkError, match="unknown scheme"):
        parse_url("http://x:1")
    with pytest.raises(LinkError, match="needs a port"):
        parse_url("udp://127.0.0.1")


async def test_request_response_and_command_ack(sim: SimFleet) -> None:
    async with Link(sim.endpoints["carrier"]) as link:
        hb = await link.expect("HEARTBEAT", sysid=12)  # registered before anything is sent
        assert hb.autopilot == M.MAV_AUTOPILOT_PX4
        # the reply to REQUEST_MESSAGE is registered before the command goes out
        fut = link.expect("AUTOPILOT_VERSION", sysid=11)
        ack = await link.command(11, M.MAV_CMD_REQUEST_MESSAGE, (M.MAVLINK_MSG_ID_AUTOPILOT_VERSION,))
        assert ack.accepted and ack.attempts == 1 and ack.sysid == 11
        version = await fut
        assert version.get_srcSystem() == 11
        unsupported = await link.command(11, M.MAV_CMD_DO_FLIGHTTERMINATION, (1,))
        assert unsupported.result_name == "MAV_RESULT_UNSUPPORTED" and not unsupported.accepted
        reply = await link.request(link.mav.ping_encode(123, 7, 0, 0), 12, "PING",
                                   match=lambda m: m.seq == 7, timeout=2.0)
        assert reply.time_usec == 123 and reply.get_srcSystem() == 12


async def test_command_retries_increment_confirmation_under_packet_loss(sim: SimFleet) -> None:
    sim.set_packet_loss(0.3, vehicle="r1")
    sent: list[int] = []
    async with Link(sim.endpoints["carrier"]) as link:
        parser = M.MAVLink(None)

        def tap(direction: str, ts: float, data: bytes) -> None:
            if direction == "out":
                for m in parser.parse_buffer(data) or []:
                    if m.get_type() == "COMMAND_LONG":
                        sent.append(m.confirmation)

        link.add_tap(tap)
        await link.expect("HEARTBEAT", sysid=1)
        acks = [await link.command(11, M.MAV_CMD_SET_MESSAGE_INTERVAL, (M.MAVLINK_MSG_ID_VFR_HUD, 5e5),
                                   timeout=0.3, retries=12) for _ in range(10)]
    assert all(a.accepted for a in acks)
    assert max(a.attempts for a in acks) > 1
    assert sorted(set(sent))[:2] == [0, 1]  # resends carry confirmation 1, 2, ...
    assert sum(a.attempts for a in acks) == len(sent)


async def test_command_without_answer_times_out(sim: SimFleet) -> None:
    sim.dropout("r2")
    async with Link(sim.endpoints["carrier"]) as link:
        with pytest.raises(LinkTimeout, match="system 12 did not acknowledge MAV_CMD_COMPONENT_ARM_DISARM"):
            await link.command(12, M.MAV_CMD_COMPONENT_ARM_DISARM, (1,), timeout=0.2, retries=2)
    assert not sim.vehicle("r2").armed


async def test_mission_round_trip_and_clear(sim: SimFleet) -> None:
    items = waypoints(40) + [MissionItem(M.MAV_CMD_NAV_LOITER_UNLIM, param4=math.nan, x=1, y=2, z=3.0)]
    async with Link(sim.endpoints["carrier"]) as link:
        await link.expect("HEARTBEAT", sysid=11)
        await link.upload_mission(11, items)
        assert len(sim.vehicle("r1").mission) == len(items)
        back = await link.download_mission(11)
        assert len(back) == len(items)
        assert all(a.same_as(b) for a, b in zip(items, back, strict=True))
        await link.clear_mission(11)
        assert await link.download_mission(11) == []
        assert sim.vehicle("r1").mission == []


@pytest.mark.slow
async def test_mission_transfer_survives_packet_loss(sim: SimFleet) -> None:
    sim.set_packet_loss(0.1, vehicle="r2")
    items = waypoints(25)
    async with Link(sim.endpoints["carrier"]) as link:
        await link.expect("HEARTBEAT", sysid=12)
        await link.upload_mission(12, items)
        back = await link.download_mission(12)
    assert all(a.same_as(b) for a, b in zip(items, back, strict=True)) and len(back) == 25
    assert sim.link_stats("r2")["rx_lost"] + sim.link_stats("r2")["tx_lost"] > 0


async def test_mission_error_ack_names_the_result_and_keeps_the_old_mission(sim: SimFleet) -> None:
    good = waypoints(3)
    bad = waypoints(2) + [MissionItem(M.MAV_CMD_DO_SET_SERVO, M.MAV_FRAME_MISSION, 1, 1500)]
    async with Link(sim.endpoints["carrier"]) as link:
        await link.expect("HEARTBEAT", sysid=11)
        await link.upload_mission(11, good)
        with pytest.raises(MissionRejected, match="MAV_MISSION_UNSUPPORTED") as exc:
            await link.upload_mission(11, bad)
        assert exc.value.result == M.MAV_MISSION_UNSUPPORTED and exc.value.sysid == 11
        back = await link.download_mission(11)
    assert len(back) == 3 and all(a.same_as(b) for a, b in zip(good, back, strict=True))


async def test_ardupilot_download_has_home_as_item_0(tmp_path: Path) -> None:
    async with sim_fleet(mission_dict(), autopilot="ardupilot") as sim, Link(sim.endpoints["r1"]) as link:
        await link.expect("HEARTBEAT", sysid=11)
        items = waypoints(4)
        await link.upload_mission(11, items)
        back = await link.download_mission(11)
    assert len(back) == 4
    assert back[0].frame == M.MAV_FRAME_GLOBAL  # home, written by the vehicle
    assert all(a.same_as(b) for a, b in zip(items[1:], back[1:], strict=True))


async def test_udpin_mode_replies_to_the_address_a_system_was_heard_from(tmp_path: Path) -> None:
    url = f"udpin://127.0.0.1:{free_udp_port()}"
    d = mission_dict(carrier_connection=url)
    async with sim_fleet(d) as sim:
        assert sim.endpoints["carrier"] == url
        mission = mission_from(d, tmp_path)
        async with await connect_fleet(mission, timeout=5.0) as fleet:
            assert list(fleet.links) == [url]
            link = fleet.links[url]
            assert set(link.routes) >= {1, 11, 12}
            await fleet.rovers["r2"].arm()
            assert sim.vehicle("r2").armed and not sim.vehicle("r1").armed


async def test_udp_mode_and_several_vehicles_on_one_link(tmp_path: Path) -> None:
    d = mission_dict(rovers=5)
    async with sim_fleet(d) as sim:
        mission = mission_from(d, tmp_path)
        async with await connect_fleet(mission, sim.endpoints, timeout=5.0) as fleet:
            assert len(fleet.links) == 1 and next(iter(fleet.links)).startswith("udp://127.0.0.1:")
            assert set(fleet.vehicles) == {"carrier", "r1", "r2", "r3", "r4", "r5"}
            assert all(v.connected for v in fleet.vehicles.values())
            await fleet.rovers["r3"].arm()
            armed = {vid for vid, v in sim.vehicles.items() if v.armed}
            assert armed == {"r3"}
            await fleet.vehicles["r3"].wait_until(lambda v: v.armed, 3.0, "armed")
            assert not fleet.vehicles["r4"].armed


async def test_rovers_with_their_own_links(tmp_path: Path) -> None:
    units = [{"id": "r1", "sysid": 11, "connection": "sim"}, {"id": "r2", "sysid": 12}]
    d = mission_dict(units=units)
    async with sim_fleet(d) as sim:
        mission = mission_from(d, tmp_path)
        async with await connect_fleet(mission, sim.endpoints, timeout=5.0) as fleet:
            assert len(fleet.links) == 2
            assert fleet.urls["r2"] == fleet.urls["carrier"] != fleet.urls["r1"]
            assert all(v.connected for v in fleet.vehicles.values())


async def test_connect_fleet_names_missing_vehicles(tmp_path: Path, sim: SimFleet) -> None:
    from fleetctl.mavlink.fleet import FleetConnectError

    d = mission_dict(rovers=3)  # the sim has only r1, r2
    mission = mission_from(d, tmp_path)
    with pytest.raises(FleetConnectError) as exc:
        await connect_fleet(mission, sim.endpoints | {"r3": sim.endpoints["carrier"]}, timeout=1.5)
    assert set(exc.value.missing) == {"r3"}
    assert f"r3 (sysid 13): no heartbeat within 1.5 s on {sim.endpoints['carrier']}" in str(exc.value)


def test_sim_connection_needs_endpoints(tmp_path: Path) -> None:
    from fleetctl.mavlink.fleet import fleet_urls

    mission = mission_from(mission_dict(), tmp_path)
    with pytest.raises(LinkError, match="start the simulated fleet"):
        fleet_urls(mission)


async def test_latency_fault_does_not_break_the_mission_protocol(sim: SimFleet) -> None:
    sim.inject(Fault("latency", vehicle="r1", seconds=0.05))
    items = waypoints(12)
    async with Link(sim.endpoints["carrier"]) as link:
        await link.expect("HEARTBEAT", sysid=11)
        await link.upload_mission(11, items)
        back = await link.download_mission(11)
    assert all(a.same_as(b) for a, b in zip(items, back, strict=True)) and len(back) == 12


async def test_tcp_link_through_a_tcp_to_udp_relay(sim: SimFleet) -> None:
    """A TCP byte stream (like a telemetry radio bridge or SITL's TCP port) relayed to the sim's UDP."""
    import asyncio
    from urllib.parse import urlsplit

    target = urlsplit(sim.endpoints["carrier"])
    loop = asyncio.get_running_loop()
    writers: list[asyncio.StreamWriter] = []

    class ToTcp(asyncio.DatagramProtocol):
        def datagram_received(self, data: bytes, addr: object) -> None:
            for w in writers:
                w.write(data)

    udp, _ = await loop.create_datagram_endpoint(ToTcp, local_addr=("127.0.0.1", 0),
                                                 remote_addr=(target.hostname, target.port))

    async def client(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        writers.append(writer)
        while data := await reader.read(4096):
            udp.sendto(data)

    server = await asyncio.start_server(client, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    try:
        async with Link(f"tcp://127.0.0.1:{port}") as link:
            await link.expect("HEARTBEAT", sysid=11)
            ack = await link.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, (1,))
            assert ack.accepted and sim.vehicle("r1").armed
            items = waypoints(6)
            await link.upload_mission(12, items)
            assert all(a.same_as(b) for a, b in zip(items, await link.download_mission(12), strict=True))
    finally:
        server.close()
        udp.close()


async def test_tcp_link_to_nobody_is_a_clear_error() -> None:
    from tests.run.ctl_helpers import free_udp_port

    url = f"tcp://127.0.0.1:{free_udp_port()}"
    with pytest.raises(LinkError, match=f"connection '{url}': cannot open"):
        await Link(url).open(timeout=2.0)
