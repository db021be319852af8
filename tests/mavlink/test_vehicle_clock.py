"""The mission clock on the vehicles' own time (fleetctl.mavlink.vehicle_clock): it follows lockstep
firmware that runs slower (or faster) than the speed-up it was asked for, never goes back, keeps
running when the vehicles are silent, lines up a rebooted vehicle and does not follow a jump - and a
run's Session on real links to a fleet whose physics runs at another pace counts the physics' time."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from fleetctl.mavlink.vehicle_clock import SILENCE_GAP, STEP_FACTOR, STEP_SLACK, VehicleTimeClock
from fleetctl.run.lifecycle import RunOptions, Session
from tests.run.ctl_helpers import mission_dict, mission_from, sim_fleet


class Wall:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


def fly(clock: VehicleTimeClock, wall: Wall, pace: float, seconds: float, sysids: tuple[int, ...] = (1,),
        boot: dict[int, float] | None = None, every: float = 0.1) -> dict[int, float]:
    """Vehicles whose clocks run ``pace`` times the wall clock, each reporting every ``every`` wall s."""
    boot = dict(boot or {s: 50.0 + 7.0 * s for s in sysids})
    for _ in range(round(seconds / every)):
        wall.t += every
        for s in sysids:
            boot[s] += every * pace
            clock.observe(s, round(boot[s] * 1000))
    return boot


def test_the_clock_counts_the_seconds_of_firmware_slower_than_its_speedup() -> None:
    wall = Wall()
    clock = VehicleTimeClock(4.0, wall)
    boot = fly(clock, wall, 4.0, 0.1)  # heard once: lined up
    t0 = clock()
    fly(clock, wall, 3.0, 10.0, boot=boot)  # the physics at 3x, asked for 4x
    flown = clock() - t0
    assert 30.0 <= flown <= 30.0 + 0.1 * 4.0  # its 30 s, at most one report interval ahead
    assert flown < 10.0 * 4.0 - 5.0  # not the wall clock times the speed-up
    assert clock.readings > 0


def test_the_clock_follows_its_reference_vehicle_then_another_when_it_stops_and_never_goes_back() -> None:
    # two SITL instances each on its own lockstep clock: 1 at 3x, 2 at 3.3x; 1 is the reference (the
    # carrier): the clock counts its seconds, not the faster one's, until its time stops (it hangs)
    wall = Wall()
    clock = VehicleTimeClock(4.0, wall)
    clock.reference = 1
    boot = {1: 100.0, 2: 7.0}
    t0, seen, t_stop = clock(), [], None
    for _ in range(100):
        wall.t += 0.1
        if wall.t < 1005.0:
            boot[1] += 0.3
        elif t_stop is None:
            t_stop = clock()
        boot[2] += 0.33
        clock.observe(2, round(boot[2] * 1000))
        clock.observe(1, round(boot[1] * 1000))
        for _ in range(3):  # looked at between the reports too: it runs on, never back
            wall.t += 0.001
            seen.append(clock())
    assert seen == sorted(seen)
    assert t_stop is not None and t_stop - t0 == pytest.approx(15.0, abs=0.5)  # vehicle 1: 5 wall s at 3x
    assert clock.leaders == [2, 1, 2]  # the first heard, the reference, the other once 1 stopped
    # vehicle 1 stopped: SILENCE_GAP wall s (the clock holding then running on at the speed-up)
    # and the rest at vehicle 2's 3.3x
    after = clock() - t_stop
    assert 3.3 * (5.3 - SILENCE_GAP) - 0.5 <= after <= 4.0 * SILENCE_GAP + 3.3 * 5.3 + 0.5


def test_silent_vehicles_leave_the_clock_on_the_wall_clock_times_the_speedup() -> None:
    wall = Wall()
    clock = VehicleTimeClock(4.0, wall)
    t0 = clock()
    wall.t += 2.0
    assert clock() - t0 == pytest.approx(8.0)  # no vehicle heard yet
    boot = fly(clock, wall, 3.0, 1.0)
    t1 = clock()
    wall.t += 5.0  # every vehicle silent: the clock goes on (waits on it end)
    assert clock() - t1 == pytest.approx(20.0, abs=0.5)
    t2 = clock()
    fly(clock, wall, 3.0, 1.0, boot={1: boot[1] + 15.0})  # heard again: its time again
    assert 3.0 - 0.5 <= clock() - t2 <= 3.0 + 0.5


def test_a_rebooted_vehicle_is_lined_up_and_a_jump_is_not_followed() -> None:
    wall = Wall()
    clock = VehicleTimeClock(4.0, wall)
    fly(clock, wall, 4.0, 1.0, boot={1: 500.0})
    t0 = clock()
    fly(clock, wall, 4.0, 1.0, boot={1: 2.0})  # rebooted: its time starts again near 0
    assert clock() - t0 == pytest.approx(4.0, abs=0.5)
    t1 = clock()
    wall.t += 0.1
    clock.observe(1, round((6.0 + 0.4 * STEP_FACTOR + STEP_SLACK + 100.0) * 1000))  # far too far
    assert clock() - t1 == pytest.approx(0.4, abs=0.01)  # the wall clock's step, not the jump
    with pytest.raises(ValueError):
        VehicleTimeClock(0.0)


async def test_a_run_on_real_links_counts_the_time_of_physics_slower_than_its_speedup(tmp_path: Path) -> None:
    """The simulated fleet's physics at 2x, fleetctl told --speedup 4 (lockstep firmware that fell
    behind): the Session's mission clock counts the physics' seconds, not wall seconds times 4."""
    d = mission_dict(speedup=2.0)
    async with sim_fleet(d) as sim:
        opts = RunOptions(endpoints=dict(sim.endpoints), clock_speedup=4.0, run_dir=tmp_path / "run",
                          connect_timeout=5.0)
        session = Session(mission_from(d, tmp_path), "deploy", opts)
        assert session.vehicle_clock is not None and session.clock is session.vehicle_clock
        try:
            fleet = await session.connect(lambda *a, **k: None)
            await fleet.carrier.wait_until(lambda v: v.enu is not None, 5.0, "position")
            await asyncio.sleep(0.3)
            c0, s0 = session.clock(), sim.sim_time
            await asyncio.sleep(2.0)
            c1, s1 = session.clock(), sim.sim_time
        finally:
            await session.close()
    physics = s1 - s0
    assert physics == pytest.approx(4.0, abs=1.0)  # 2 wall s at 2x
    assert c1 - c0 == pytest.approx(physics, abs=0.6)  # the physics' time, within a report or two
    assert session.vehicle_clock.readings > 0


def test_docs_autopilots_states_the_clock_on_the_vehicles_time() -> None:
    text = " ".join((Path(__file__).resolve().parents[2] / "docs" / "autopilots.md").read_text().split())
    assert "fleetctl/mavlink/vehicle_clock.py" in text
    assert f"while its time stands still for {SILENCE_GAP:g} wall s" in text
