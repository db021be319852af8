"""A rover down on the deck is disarmed before it counts as loaded (CollectPhase._disarmed_on_deck).
A PX4 rover is told to at once when its land detector reports it landed or when it is at rest
(collect._at_rest): PX4 SIH's land detector missed a landing while the rover stood on the ground
beside the carrier, its velocity estimate reading 0.3 - 0.4 m/s (its positions moved 0.1 m/s), and
the rover was disarmed only DISARM_WAIT later (collect +32 %). One still descending is not."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.geo import Origin
from fleetctl.mavlink.autopilots import ArduPilot, Px4
from fleetctl.mavlink.link import Link
from fleetctl.mavlink.messages import CommandAck
from fleetctl.mavlink.vehicle import CommandRejected, Vehicle
from fleetctl.run.collect import DISARM_WAIT, REST_WINDOW, CollectPhase, _at_rest
from tests.run.ctl_helpers import apply_positions

ORIGIN = Origin(47.397742, 8.545594, 488.0)


def rover(autopilot: Any, track: list[tuple[float, float, float, float]]) -> Vehicle:
    """A rover (never connected) with GLOBAL_POSITION_INT reports applied: (vehicle s, east m,
    velocity estimate east m/s, up m/s)."""
    v = Vehicle(Link("udp://127.0.0.1:9"), 11, name="r1", origin=ORIGIN)
    v.autopilot, v.armed = autopilot, True
    apply_positions(v, ORIGIN, track)
    return v


def standing(ve: float, vu: float = 0.0, creep: float = 0.01) -> list[tuple[float, float, float, float]]:
    """1.5 s of reports 0.1 s apart: moving ``creep`` m per report, the estimate reading ``ve``."""
    return [(20.0 + 0.1 * i, creep * i, ve, vu) for i in range(16)]


class _Ctx:
    """What ``_disarmed_on_deck`` uses of a run's context: a wait looks at the rover once and, if it
    is not done, runs out (the clock moves on by the wait); commands are journalled only."""

    def __init__(self, refuse: int = 0, during_waits: list[Callable[[Vehicle], None]] | None = None) -> None:
        self.now, self.log = 0.0, []  # type: ignore[var-annotated]
        self.refuse = refuse  # this many disarms are refused ("Disarming denied: not landed")
        self.during_waits = list(during_waits or [])  # what happens to the rover during each wait
        self.state = SimpleNamespace(set_state=lambda *_a: None)
        self.mission = SimpleNamespace(rovers=SimpleNamespace(takeoff_time=1.0, climb_rate=1.0))

    def clock(self) -> float:
        return self.now

    def record(self, kind: str, **data: Any) -> None:
        self.log.append(("record", kind))

    async def wait_for(self, v: Vehicle, predicate: Callable[[Vehicle], bool], seconds: float,
                       what: str) -> None:
        if self.during_waits:
            self.during_waits.pop(0)(v)
        if not predicate(v):
            self.now += seconds
            self.log.append(("waited", seconds))
            raise TimeoutError(what)

    async def command(self, v: Vehicle, what: str, aw: Any, **data: Any) -> None:
        aw.close()  # (not sent: the rover is never connected)
        self.log.append(("command", what))
        if what == "disarm" and self.refuse > 0:
            self.refuse -= 1
            ack = CommandAck(v.sysid, M.MAV_CMD_COMPONENT_ARM_DISARM, M.MAV_RESULT_DENIED, 1)
            raise CommandRejected(v.name, ack, "not landed")


def disarm(v: Vehicle, ctx: _Ctx | None = None) -> list[tuple[str, Any]]:
    ctx = ctx or _Ctx()
    asyncio.run(CollectPhase._disarmed_on_deck(SimpleNamespace(ctx=ctx), v))  # type: ignore[arg-type]
    return ctx.log


def landed(v: Vehicle) -> None:
    v.landed_state = M.MAV_LANDED_STATE_ON_GROUND


def test_a_px4_rover_refused_at_rest_is_told_again_once_it_reports_itself_landed() -> None:
    """PX4 SIH refused a disarm at rest ("Disarming denied: not landed"), detected the landing 2.3 s
    later and disarmed itself 1.7 s after that: it is told again as soon as it reports itself landed."""
    v = rover(Px4(M.MAV_TYPE_QUADROTOR), standing(0.35))
    log = disarm(v, _Ctx(refuse=1, during_waits=[lambda v: None, landed]))
    assert log == [("command", "disarm"), ("command", "disarm")]


def test_a_rover_beside_the_deck_is_disarmed_then_armed_before_its_take_off() -> None:
    """Its disarm's ACK comes before the HEARTBEAT that shows it disarmed: it is armed again all the
    same (PX4 SIH, told to take off while still disarming, stayed on the ground)."""
    v = rover(Px4(M.MAV_TYPE_QUADROTOR), standing(0.0))
    landed(v)
    ctx = _Ctx()
    phase = SimpleNamespace(ctx=ctx, _disarmed_on_deck=lambda v: CollectPhase._disarmed_on_deck(phase, v))
    with pytest.raises(TimeoutError):  # (the scripted rover never climbs)
        asyncio.run(CollectPhase._lift_again(phase, v, 1.7, 0))  # type: ignore[arg-type]
    assert v.armed  # its HEARTBEAT has not come yet
    assert [c for c in ctx.log if c[0] == "command"] == [("command", "disarm"), ("command", "arm"),
                                                         ("command", "takeoff")]


def test_a_px4_rover_at_rest_is_disarmed_at_once_whatever_its_land_detector_says() -> None:
    v = rover(Px4(M.MAV_TYPE_QUADROTOR), standing(0.35))  # SIH: estimate 0.35 m/s, positions 0.1 m/s
    assert v.on_ground is None and _at_rest(v)
    assert disarm(v) == [("command", "disarm")]


def test_a_px4_rover_still_coming_down_is_not_disarmed_before_disarm_wait() -> None:
    v = rover(Px4(M.MAV_TYPE_QUADROTOR), standing(0.1, vu=-0.66))  # descending at 0.66 m/s
    assert not _at_rest(v)
    assert disarm(v) == [("waited", DISARM_WAIT), ("command", "disarm")]


def test_a_rover_moving_by_its_positions_is_not_at_rest() -> None:
    v = rover(Px4(M.MAV_TYPE_QUADROTOR), standing(0.35, creep=0.05))  # 0.5 m/s by its positions
    assert not _at_rest(v)
    short = rover(Px4(M.MAV_TYPE_QUADROTOR), standing(0.35)[:3])  # 0.2 s of positions: not enough
    assert REST_WINDOW > 0.2 and not _at_rest(short)
    assert _at_rest(rover(Px4(M.MAV_TYPE_QUADROTOR), standing(0.1)[:1]))  # its estimate: at rest


@pytest.mark.parametrize("on_ground", [None, True])
def test_an_ardupilot_rover_disarms_itself_first(on_ground: bool | None) -> None:
    """ArduCopter disarms itself about 2 s after its touch-down: it is given DISARM_WAIT first."""
    v = rover(ArduPilot(M.MAV_TYPE_QUADROTOR), standing(0.0))
    v.landed_state = M.MAV_LANDED_STATE_ON_GROUND if on_ground else None
    assert disarm(v) == [("waited", DISARM_WAIT), ("command", "disarm")]


def test_the_docs_state_when_a_px4_rover_is_told_to_disarm() -> None:
    from pathlib import Path

    from fleetctl.run.collect import REST_SPEED
    text = " ".join((Path(__file__).resolve().parents[2] / "docs" / "mavlink.md").read_text().split())
    assert (f"is at rest on the deck - slower than {REST_SPEED:g} m/s vertically, and horizontally by its "
            f"velocity estimate or by its positions over the last {REST_WINDOW:g} s of its own clock") in text
