"""A vehicle is lost after ``links.heartbeat_timeout`` of mission time (fleetctl.mavlink.silence): the
rule itself, a fleet running 20 times faster than real time (lost after a dropout far shorter than
the timeout in wall seconds), the wall-clock floor (a lossy link at speed-up 20 does not lose healthy
vehicles) and a busy event loop (its late look gives the vehicle the floor once more)."""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

from fleetctl.mavlink.fleet import Fleet, connect_fleet
from fleetctl.mavlink.silence import LOST_WALL_FLOOR, silence_left
from fleetctl.mavlink.vehicle import VehicleEvent
from tests.run.ctl_helpers import mission_dict, mission_from, sim_fleet


def test_at_speedup_1_the_timeout_is_the_wall_clocks() -> None:
    for silent in (0.0, 1.0, 2.5, 3.0, 4.0):
        assert silence_left(3.0, silent, silent, 1.0) == 3.0 - silent


def test_faster_than_real_time_the_timeout_is_in_mission_seconds_above_a_wall_floor() -> None:
    # speed-up 20, 3 mission s: 0.15 wall s by the mission clock, but never under the wall floor
    assert silence_left(3.0, 0.5, 10.0, 20.0) == LOST_WALL_FLOOR - 0.5
    assert silence_left(3.0, LOST_WALL_FLOOR, 20.0 * LOST_WALL_FLOOR, 20.0) <= 0.0
    # at speed-up 2 the mission clock decides: 3 mission s are 1.5 wall s
    assert silence_left(3.0, 1.0, 2.0, 2.0) == 0.5
    # a simulator lagging behind its speed-up: its clock, not the wall clock times 20, counts
    assert silence_left(3.0, 2.0, 1.0, 20.0) == 0.1
    # a timeout shorter than the floor is a floor of its own length (a real link: the timeout)
    assert silence_left(0.5, 0.4, 0.4, 1.0) > 0.0 and silence_left(0.5, 0.5, 0.5, 1.0) == 0.0


@contextlib.asynccontextmanager
async def fleet_at_speedup_20(
        tmp_path: Path, clock: str = "sim") -> AsyncIterator[tuple[Any, Fleet, list[VehicleEvent]]]:
    """A simulated fleet at speed-up 20 with ``links.heartbeat_timeout`` 3 mission s, connected; every
    vehicle on the simulator's clock (``clock="sim"``) or on the wall clock times the speed-up
    (``"wall"``: vehicles elsewhere, whose time goes on while the controller's loop is blocked), and
    every vehicle event collected."""
    d = mission_dict(heartbeat_timeout=3.0, speedup=20.0)
    async with sim_fleet(d) as sim:
        async with await connect_fleet(mission_from(d, tmp_path), sim.endpoints, timeout=5.0) as fleet:
            events: list[VehicleEvent] = []
            for v in fleet.vehicles.values():
                if clock == "sim":
                    v.use_clock(lambda: float(sim.sim_time), sim.speedup)
                else:
                    v.use_clock(lambda: time.monotonic() * sim.speedup, sim.speedup)
                v.add_listener(events.append)
            yield sim, fleet, events


def _lost_and_back(events: list[VehicleEvent], name: str) -> list[str]:
    return [ev.kind for ev in events if ev.vehicle == name and ev.kind in ("lost", "back")]


async def test_a_dropout_of_many_mission_timeouts_is_a_loss_at_speedup_20(tmp_path: Path) -> None:
    """3 s of mission time at speed-up 20: a 1.6 wall s dropout (32 mission s) is a loss, where a
    wall-clock timeout of 3 s would not have seen it."""
    async with fleet_at_speedup_20(tmp_path) as (sim, fleet, events):
        sim.dropout("r1", duration=1.6 * sim.speedup)
        r1 = fleet.rovers["r1"]
        await r1.wait_until(lambda v: v.lost, 10.0, "lost")
        await r1.wait_until(lambda v: not v.lost, 10.0, "back")
        assert _lost_and_back(events, "r1") == ["lost", "back"]
        assert not fleet.carrier.lost and not fleet.rovers["r2"].lost


async def test_a_lossy_link_at_speedup_20_loses_no_healthy_vehicle(tmp_path: Path) -> None:
    """3 mission s are 0.15 wall s at speed-up 20, about the gap between two positions: only the
    wall floor keeps a 40 % lossy link's vehicles from being lost all the time."""
    async with fleet_at_speedup_20(tmp_path) as (sim, _fleet, events):
        sim.set_packet_loss(0.4)
        await asyncio.sleep(3.0)
        assert [ev for ev in events if ev.kind == "lost"] == []
        assert sim.link_stats("r1")["tx_lost"] > 0


async def test_a_busy_event_loop_does_not_lose_healthy_vehicles(tmp_path: Path) -> None:
    """The controller's loop blocked for longer than the floor and many mission timeouts, on the
    clock of vehicles elsewhere (the wall clock times their speed-up, which goes on while the loop
    is blocked): the late silence check looks again once the vehicles' messages can be read."""
    async with fleet_at_speedup_20(tmp_path, clock="wall") as (_sim, _fleet, events):
        await asyncio.sleep(0.5)
        time.sleep(1.5 * LOST_WALL_FLOOR)  # a blocking call in the loop: the simulator stalls too
        await asyncio.sleep(2.0)
        assert [ev for ev in events if ev.kind == "lost"] == []
