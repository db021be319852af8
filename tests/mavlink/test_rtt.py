"""The retransmission timeout of a link (fleetctl.mavlink.rtt): the protocol's timeout until a round
trip is known, then a few round trips, never below MIN_RTO nor above the protocol's timeout; and
on a lossy link a command is resent after that, not after a whole second."""

from __future__ import annotations

from fleetctl.mavlink.rtt import MIN_RTO, RoundTrip
from sitl import Fault
from tests.run.ctl_helpers import mission_dict, mission_from, sim_fleet


def test_the_timeout_follows_the_round_trips() -> None:
    rt = RoundTrip()
    assert rt.timeout(1.0) == 1.0  # nothing measured yet
    for _ in range(20):
        rt.add(0.002)
    assert rt.timeout(1.0) == MIN_RTO  # a fast link: the floor
    for _ in range(50):
        rt.add(0.4)
    assert 0.4 <= rt.timeout(1.0) <= 1.0
    for _ in range(50):
        rt.add(3.0)
    assert rt.timeout(1.0) == 1.0  # never above the protocol's timeout
    rt.add(-1.0)  # a clock step: ignored
    assert rt.samples == 120


async def test_a_lost_command_is_resent_after_the_links_timeout(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from fleetctl.mavlink.fleet import connect_fleet

    d = mission_dict(rovers=1)
    mission = mission_from(d, tmp_path)
    async with sim_fleet(d) as sim, await connect_fleet(mission, sim.endpoints, timeout=5.0) as fleet:
        r1 = fleet.rovers["r1"]
        link = r1.link
        for _ in range(5):  # round trips measured on a clean link
            await r1.request_message(0, timeout=1.0)
        assert link.rtt.samples >= 5 and MIN_RTO <= link.rtt.timeout(1.0) < 0.5
        sim.inject(Fault("dropout", vehicle="r1", at=sim.sim_time, until=sim.sim_time + 0.4 * sim.speedup))
        waits = []
        timeout = link.rtt.timeout

        def spy(ceiling: float) -> float:
            waits.append(timeout(ceiling))
            return waits[-1]

        link.rtt.timeout = spy  # type: ignore[method-assign]
        ack = await r1.request_message(0, timeout=1.0)
        # the first attempts fall in the dropout; each waited the link's timeout, not a second
        assert ack.attempts >= 2 and len(waits) == ack.attempts, (ack, waits)
        assert all(w < 1.0 for w in waits), waits
