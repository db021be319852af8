"""A rover that cannot arrive is let go at once, and every wait is a deadline in mission
time. End to end through the simulated fleet (bench/faults.py's scenario: r2 dies or fails safe on
its way to its collection stop); times are simulated seconds."""

from __future__ import annotations

import asyncio
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from bench.faults import VICTIM, fly
from fleetctl.run.context import REPORT_WAIT, RunContext
from fleetctl.run.kinds import VehicleStatus
from fleetctl.run.state import VehicleState
from fleetctl.run.summary import _is_airborne
from fleetctl.run.trouble import Trouble

DETECT = 2.0  # mission s from the evidence to the rover let go (the target)


def _check_let_go(row: dict[str, Any], why: str) -> None:
    assert row["result"] == "complete", row
    assert sorted(row["loaded"]) == ["r1", "r3"], row
    assert why in row["let_go"].get(VICTIM, ""), row
    # polled every 2 ms of wall time: the evidence lies between the poll before and the one that saw it
    assert row["detection"] is not None and row["detection"] <= DETECT, row
    assert row["detection_max"] is not None and row["detection_max"] >= -0.1, row
    v = row["victim"]
    assert v["battery_pct"] is not None and v["position"] is not None and v["state"], v
    assert row["flown"] is not None


@pytest.mark.slow
async def test_a_rover_dying_on_its_way_is_let_go_and_the_decisions_do_not_depend_on_the_speedup(
        tmp_path: Path) -> None:
    fast = await fly("battery", 20.0, tmp_path)
    slow = await fly("battery", 1.0, tmp_path)
    for row in (fast, slow):
        _check_let_go(row, "")
        assert VICTIM in row["let_go"]
    # the same decisions; why it was let go is the first evidence to arrive: the empty battery or
    # the LAND its autopilot switched to because of it (which comes first depends on the messages)
    truths = ("battery empty", "switched to LAND")
    for row in (fast, slow):
        assert all(d[2] in truths for d in row["decisions"] if d[0] == "rover_let_go"), row["decisions"]

    def acts(row: dict[str, Any]) -> list[Any]:
        return [d if d[0] != "rover_let_go" else d[:2] for d in row["decisions"]]

    assert acts(fast) == acts(slow), (fast["decisions"], slow["decisions"])
    # the same flight, within what the machine's load adds at speed-up 20: a stall of 0.15 wall s
    # is 3 mission s there (a loaded CI machine flew it 14.9 s against 11.8 s), so the bound is
    # relative; a decision that waited for a wall-time timeout would double the flight
    gap = abs(fast["flown"] - slow["flown"])
    assert gap < max(3.0, 0.4 * slow["flown"]), (fast["flown"], slow["flown"])


@pytest.mark.parametrize("fault,why", [("rtl", "RTL"), ("land", "LAND")])
async def test_a_rover_switching_to_a_failsafe_mode_is_let_go(tmp_path: Path, fault: str, why: str) -> None:
    row = await fly(fault, 20.0, tmp_path)
    _check_let_go(row, why)
    if fault == "land":  # it landed where it was, short of its stop: on the ground, by telemetry
        assert row["victim"]["airborne"] is False, row["victim"]


def test_airborne_follows_telemetry_not_the_last_command() -> None:
    landed = VehicleState("r1", "rover", 11, state=VehicleStatus.ON_TASK, alt=0.0, on_ground=True)
    flying = VehicleState("r2", "rover", 12, state=VehicleStatus.LANDED, alt=4.0, on_ground=False)
    no_landed_state = VehicleState("r3", "rover", 13, state=VehicleStatus.ON_TASK, alt=2.0, connected=True)
    unknown = VehicleState("r4", "rover", 14, state=VehicleStatus.ON_TASK)
    assert _is_airborne(landed) is False
    assert _is_airborne(flying) is True
    assert _is_airborne(no_landed_state) is True
    assert _is_airborne(unknown) is None


def test_a_flight_reported_after_the_last_telemetry_is_airborne() -> None:
    """Telemetry lags at a high speed-up: a rover that reached its task after its last landed state
    (still ON_GROUND from the deck) is in the air; one whose landed state came later is not."""
    stale = VehicleState("r1", "rover", 11, state=VehicleStatus.ON_TASK, alt=0.0, on_ground=True,
                         telemetry_at=10.0, state_at=11.0)
    fresh = VehicleState("r2", "rover", 12, state=VehicleStatus.ON_TASK, alt=0.0, on_ground=True,
                         telemetry_at=12.0, state_at=11.0)
    assert _is_airborne(stale) is True
    assert _is_airborne(fresh) is False


def test_a_land_the_controller_commanded_is_not_a_failsafe() -> None:
    rover = SimpleNamespace(on_ground=False, battery_pct=50.0, armed=True, mode="LAND", critical=False,
                            enu=(0.0, 0.0, 3.0), ground_speed=0.0)
    assert Trouble(lambda: ((0.0, 0.0, 0.0),), failsafe=True).seen(rover)  # type: ignore[arg-type]
    ours = Trouble(lambda: ((0.0, 0.0, 0.0),), failsafe=True)
    ours.commanded("LAND")
    assert not ours.seen(rover)  # type: ignore[arg-type]
    rover.mode = "RTL"
    assert ours.seen(rover) and ours.why == "switched to RTL (failsafe)"  # type: ignore[arg-type]


class _Still:
    """A vehicle whose condition never holds (wait_until times out after its wall timeout)."""

    name, sysid = "r9", 19

    async def wait_until(self, predicate: Any, timeout: float, what: str = "") -> None:
        await asyncio.sleep(timeout)
        raise TimeoutError(what)


@pytest.mark.parametrize("speedup", [1.0, 20.0])
async def test_a_wait_gives_up_on_its_mission_time_deadline(speedup: float) -> None:
    t0 = time.monotonic()

    def clock() -> float:
        return (time.monotonic() - t0) * speedup

    state = SimpleNamespace(mission_clock=None)
    ctx = RunContext(SimpleNamespace(), SimpleNamespace(), state, speedup=speedup, clock=clock)  # type: ignore[arg-type]
    start = clock()
    with pytest.raises(TimeoutError, match="mission time"):
        await ctx.wait_for(_Still(), lambda v: False, 1.0 * speedup / 4, "meeting point")  # type: ignore[arg-type]
    waited = clock() - start
    # the mission deadline, then REPORT_WAIT wall s for a last report; not the 15 wall s backstop
    assert speedup / 4 <= waited <= speedup / 4 + (REPORT_WAIT + 0.5) * speedup, waited
