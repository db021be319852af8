"""A collection is planned from fresh batteries: Vehicle.refresh_battery asks for BATTERY_STATUS."""

from __future__ import annotations

from fleetctl.mavlink.fleet import Fleet
from sitl import SimFleet


async def test_refresh_battery_reads_the_battery_now(fleet: Fleet, sim: SimFleet) -> None:
    r1 = fleet.rovers["r1"]
    await r1.wait_until(lambda v: v.battery_pct is not None, 3.0, "telemetry")
    # stream the battery only every 50 s, then drain it in the simulated world
    await r1.configure_streams(battery_hz=0.02)
    sim.rover("r1").battery = 0.42
    assert r1.battery_pct == 100.0
    assert await r1.refresh_battery(timeout=3.0) == 42.0
    assert r1.battery_pct == 42.0


async def test_refresh_battery_is_bounded_by_its_timeout(fleet: Fleet, sim: SimFleet) -> None:
    """A vehicle that does not answer REQUEST_MESSAGE costs the caller its timeout, not one
    timeout per command attempt (8 attempts used to stall the collection plan for 8 s): the
    attempts share the budget, each waiting at most a quarter of it and at least the link's
    shortest retransmission timeout, so no more than budget / MIN_RTO fill it and one more at most
    starts at its end (a loaded machine sends fewer, never more), and the last known reading comes
    back."""
    from pymavlink.dialects.v20 import common as mavlink2

    from fleetctl.mavlink.rtt import MIN_RTO
    from sitl.faults import Fault

    r1 = fleet.rovers["r1"]
    await r1.wait_until(lambda v: v.battery_pct is not None, 3.0, "telemetry")
    before = r1.battery_pct
    sim.faults.add(Fault(kind="dropout", vehicle="r1", at=0.0))
    parser = mavlink2.MAVLink(None)
    requests: list[int] = []  # the attempt number (confirmation) of every REQUEST_MESSAGE to r1

    def tap(direction: str, _t: float, data: bytes) -> None:
        for m in (parser.parse_buffer(data) or []) if direction == "out" else []:
            if (m.get_type() == "COMMAND_LONG" and m.target_system == r1.sysid
                    and m.command == mavlink2.MAV_CMD_REQUEST_MESSAGE):
                requests.append(m.confirmation)

    remove = fleet.add_tap(tap)
    try:
        assert await r1.refresh_battery(timeout=1.0) == before  # the last known reading
    finally:
        remove()
    assert 1 <= len(requests) <= round(1.0 / MIN_RTO) + 1 and requests == list(range(len(requests))), requests
