"""Fault injection (config and Python API) and robustness against malformed datagrams."""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M
from sitl_helpers import ORIGIN, Gcs, enu_to_latlon, make_config, open_gcs

from sitl import Fault, FaultError, SimFleet


async def test_dropout_is_silent_and_deaf_then_back(fleet: SimFleet, gcs: Gcs) -> None:
    fleet.dropout("r1", duration=30.0)  # simulated seconds: 1.5 s of wall time at 20x
    until = fleet.sim_time + 30.0
    since = gcs.mark()
    gcs.send(gcs.mav.command_long_encode(11, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0))
    await gcs.recv("GLOBAL_POSITION_INT", sysid=12, since=since)  # the others keep talking
    await gcs.none("COMMAND_ACK", sysid=11, since=since, wait=0.3)
    assert not fleet.vehicle("r1").armed  # deaf
    assert all(m.get_srcSystem() != 11 for m in gcs.received[since:] if fleet.sim_time < until)
    assert fleet.link_stats()["rx_deaf"] >= 1 and fleet.link_stats()["tx_silent"] >= 1
    back = await gcs.recv("HEARTBEAT", sysid=11, since=since, timeout=5.0)
    assert back is not None and fleet.sim_time >= until
    ack = await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    assert ack.result == M.MAV_RESULT_ACCEPTED


async def test_dropout_from_the_mission_file_at_a_simulated_time() -> None:
    cfg = make_config(1, speedup=20.0, faults=[Fault("dropout", vehicle="r1", at=20.0)])
    async with SimFleet(cfg) as fleet:
        gcs = await open_gcs(fleet.endpoints["carrier"])
        try:
            await gcs.recv("GLOBAL_POSITION_INT", sysid=11)
            assert fleet.sim_time < 20.0
            await fleet.wait_sim_time(21.0, timeout=5)
            since = gcs.mark()
            await gcs.recv("GLOBAL_POSITION_INT", sysid=1, since=since)
            await gcs.none("GLOBAL_POSITION_INT", sysid=11, since=since, wait=0.5)  # never back
        finally:
            gcs.close()


async def test_the_vehicle_keeps_flying_its_mission_during_a_dropout(fleet: SimFleet, gcs: Gcs) -> None:
    await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    await gcs.command(11, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, ORIGIN[2] + 10.0)
    fleet.dropout("r1")
    rover = fleet.rover("r1")
    await fleet.wait_for(lambda: rover.position[2] > 9.9, timeout=5)


async def test_packet_loss_drops_the_given_share(fleet: SimFleet, gcs: Gcs) -> None:
    fleet.set_packet_loss(1.0, vehicle="r1")
    since = gcs.mark()
    await gcs.recv("GLOBAL_POSITION_INT", sysid=12, since=since)
    await gcs.none("GLOBAL_POSITION_INT", sysid=11, since=since, wait=0.4)
    fleet.set_packet_loss(0.0, vehicle="r1")
    await gcs.recv("GLOBAL_POSITION_INT", sysid=11, since=gcs.mark())

    for sysid in (1, 11, 12):
        await gcs.command(sysid, M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 20_000)
    fleet.set_packet_loss(0.5)
    before = fleet.link_stats()
    since = gcs.mark()
    await fleet.wait_for(lambda: fleet.link_stats()["tx_lost"] - before["tx_lost"] >= 150, timeout=10)
    after = fleet.link_stats()
    fleet.set_packet_loss(0.0)
    lost = after["tx_lost"] - before["tx_lost"]
    sent = after["tx_messages"] - before["tx_messages"]
    assert 0.35 < lost / (lost + sent) < 0.65
    assert len(gcs.received) - since <= sent  # what the GCS got was sent, nothing more


async def test_packet_loss_hits_uplink_too(fleet: SimFleet, gcs: Gcs) -> None:
    fleet.set_packet_loss(1.0, vehicle="r2")
    since = gcs.mark()
    gcs.send(gcs.mav.command_long_encode(12, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0))
    await gcs.none("COMMAND_ACK", sysid=12, since=since, wait=0.3)
    assert not fleet.vehicle("r2").armed
    assert fleet.link_stats()["rx_lost"] >= 1


async def test_latency_delays_both_directions(fleet: SimFleet, gcs: Gcs) -> None:
    loop_time = __import__("asyncio").get_running_loop().time
    fleet.set_latency(0.15, vehicle="r1")
    since = gcs.mark()
    t0 = loop_time()
    gcs.send(gcs.mav.ping_encode(1, 1, 0, 0))
    await gcs.recv("PING", sysid=12, since=since)
    await gcs.recv("PING", sysid=11, since=since)
    assert loop_time() - t0 >= 0.3  # 0.15 s up and 0.15 s down (a lower bound, never flaky)
    fleet.set_latency(0.0, vehicle="r1")


async def test_battery_drain_factor(fleet: SimFleet, gcs: Gcs) -> None:
    fleet.inject(Fault("battery_drain", vehicle="r2", factor=3.0))
    for sysid in (11, 12):
        await gcs.command(sysid, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        ack = await gcs.command(sysid, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan,
                                ORIGIN[2] + 10.0)
        assert ack.result == M.MAV_RESULT_ACCEPTED
    r1, r2 = fleet.rover("r1"), fleet.rover("r2")
    await fleet.wait_for(lambda: r1.arrived and r2.arrived and r1.position[2] > 9 and r2.position[2] > 9,
                         timeout=5)
    # per second in the air (5 m/s on 200 m: 2.5 %/s), three times as fast for r2; at least the
    # 2 s climb to 10 m
    used1, used2 = 1.0 - r1.battery, 1.0 - r2.battery
    assert used1 >= 2.0 * 5.0 / 200.0 - 1e-6
    assert used2 == pytest.approx(3 * used1, rel=0.15)
    level = r2.battery
    st = await gcs.recv("BATTERY_STATUS", sysid=12, since=gcs.mark())
    assert st.battery_remaining <= round(100 * level)


async def test_empty_battery_lands_the_rover() -> None:
    cfg = make_config(1, endurance_range=20.0, faults=[Fault("battery_drain", vehicle="r1", factor=2.0)])
    async with SimFleet(cfg) as fleet:
        gcs = await open_gcs(fleet.endpoints["r1"])
        try:
            await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
            nan = math.nan
            await gcs.command(11, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, nan, nan, nan, ORIGIN[2] + 3.0)
            rover = fleet.rover("r1")
            await fleet.wait_for(lambda: rover.arrived and rover.position[2] > 2.9, timeout=5)
            lat, lon = enu_to_latlon(30.0, 0.0)
            ack = await gcs.command_int(11, M.MAV_CMD_DO_REPOSITION, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                                        (-1, 1, 0, math.nan), lat, lon, 3.0)
            assert ack.result == M.MAV_RESULT_ACCEPTED
            await fleet.wait_for(lambda: rover.on_ground, timeout=5)
            # 20 m of endurance at drain factor 2 = 2 s in the air at 5 m/s: 0.6 s up to 3 m, at
            # most 1.4 s (7 m) across, less the hover before the reposition, then down where its
            # landing mode brings it (PX4's LAND travels on 1.2 s of its 5 m/s: land_travel)
            assert rover.battery == 0.0 and not rover.loaded
            x, y, z = rover.position
            assert 0.5 < x <= 7.0 + 5.0 * rover.land_travel + 0.15
            assert y == pytest.approx(0.0, abs=0.05) and z == 0.0
            v = fleet.vehicle("r1")
            assert any("Battery empty" in text for _, _, text in v.statustexts)
            await fleet.wait_for(lambda: not v.armed, timeout=5)
            ack = await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
            assert ack.result == M.MAV_RESULT_DENIED
        finally:
            gcs.close()


async def test_refuse_arm(fleet: SimFleet, gcs: Gcs) -> None:
    fleet.inject(Fault("refuse_arm", vehicle="r1"))
    since = gcs.mark()
    ack = await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    assert ack.result == M.MAV_RESULT_DENIED and not fleet.vehicle("r1").armed
    text = await gcs.recv("STATUSTEXT", sysid=11, since=since)
    assert "denied" in text.text.lower()
    assert (await gcs.command(12, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)).result == M.MAV_RESULT_ACCEPTED
    fleet.clear_faults("refuse_arm", vehicle="r1")
    assert (await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)).result == M.MAV_RESULT_ACCEPTED


def test_fault_validation() -> None:
    with pytest.raises(FaultError, match="kind"):
        Fault("meteor")
    with pytest.raises(FaultError, match="until"):
        Fault("dropout", at=10.0, until=5.0)
    with pytest.raises(FaultError, match="rate"):
        Fault.from_dict({"kind": "packet_loss"})
    with pytest.raises(FaultError, match="unknown key"):
        Fault.from_dict({"kind": "latency", "seconds": 0.1, "rate": 0.3})
    f = Fault.from_dict({"vehicle": "r3", "kind": "dropout", "at": 20.0, "until": 45.0})
    assert f.applies("r3", 20.0) and f.applies("r3", 44.9) and not f.applies("r3", 45.0)
    assert not f.applies("r2", 30.0) and not f.applies("r3", 19.9)


async def test_malformed_datagrams_are_counted_and_dropped(fleet: SimFleet, gcs: Gcs) -> None:
    arm = gcs.mav.command_long_encode(11, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
    good = arm.pack(gcs.mav)
    corrupt = bytearray(good)
    corrupt[12] ^= 0xFF  # payload byte: CRC mismatch
    before = fleet.link_stats()
    gcs.send_raw(b"\x00garbage that is not mavlink\xff" * 3)
    gcs.send_raw(good[:9])  # truncated header
    gcs.send_raw(good[:-4])  # truncated payload/CRC
    gcs.send_raw(bytes(corrupt))
    gcs.send_raw(bytes(range(256)) * 4)
    gcs.send_raw(b"\xfd\xff" + b"\x00" * 30)  # claims a 255-byte payload
    await fleet.wait_for(lambda: fleet.link_stats()["rx_datagrams"] - before["rx_datagrams"] >= 6, timeout=3)
    after = fleet.link_stats()
    assert after["rx_bad"] - before["rx_bad"] >= 3
    assert after["rx_truncated"] - before["rx_truncated"] >= 3
    assert not fleet.vehicle("r1").armed  # the corrupted command was not executed
    ack = await gcs.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)  # and the link still works
    assert ack.result == M.MAV_RESULT_ACCEPTED
    assert fleet.errors == 0
