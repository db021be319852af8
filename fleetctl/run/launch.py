"""Launching a rover from the carrier's deck: deck check, mission upload, arm, start, lift-off, and
a spare from the deck when the planned rover cannot go.

Any rover on the deck may fly any task of a stop. :meth:`Launcher.launch` tries the planned rover
first; a rover that is not on the deck, refuses to arm, fails its upload or does not lift off is
replaced by the next spare (:class:`Spares`). Before arming, a ``launch`` record (rover, task,
stop) is on disk, so a journal cut short by a crash says which rover was being sent where.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass, field

from fleetctl.mavlink.compile import RoverMission
from fleetctl.mavlink.link import LinkError
from fleetctl.mavlink.vehicle import CommandRejected, Vehicle
from fleetctl.mission.flight import TAKEOFF_HEIGHT
from fleetctl.run.carrier import CarrierControl, upload
from fleetctl.run.context import ExecutionError, RunContext
from fleetctl.run.kinds import Ev, VehicleStatus
from fleetctl.run.state import on_deck
from fleetctl.run.task_board import TaskBoard

AIRBORNE_HEIGHT = 0.3  # m above home: a launched rover is off the deck
# m above home: a launched rover is clear of the deck, the carrier may go (with the take-off item
# reached, whichever comes first): the top of its take-off, which the time model's takeoff_time
# climbs to (an autopilot may report the item reached a little below it)
CLEAR_HEIGHT = TAKEOFF_HEIGHT - 0.05
DECK_CHECK_TIMEOUT = 2.0  # wall s for fresh telemetry to show a rover on the (stopped) carrier's deck
RANGE_TOLERANCE = 1e-4  # m: a flight this much over a spare's range is within it (rounding)
LIFTOFF_TIMEOUT = 5.0  # mission s from start_mission to clear of the deck (at least; 3x takeoff_time)

Vec3 = tuple[float, float, float]


def rover_on_deck(ctx: RunContext, v: Vehicle) -> bool:
    c = ctx.fleet.carrier
    return v.connected and not v.lost and on_deck(v.enu, c.enu, v.on_ground, v.ground_speed, v.height,
                                                  ctx.mission.carrier.deck_height)


def takeoff_seq(slot: RoverMission) -> int:
    """Index of the NAV_TAKEOFF item of a compiled rover mission (-1 if it has none)."""
    return slot.takeoff_seq


def flight_path(ctx: RunContext, rm: RoverMission, start: Vec3) -> list[Vec3]:
    """Where a rover flying ``rm`` from ``start`` should be (its items' positions)."""
    origin = ctx.fleet.carrier.origin
    return [start] if origin is None else [start, *rm.positions(origin)]


@dataclass
class Spares:
    """The rovers on the deck that no stop of the current plan uses. A spare takes a planned
    rover's flight only when its battery range (``ranges``, planning range per rover; absent =
    the mission's deploy range) covers that flight (``needs``: planned rover -> flight length)."""

    rovers: list[str]
    used: set[str] = field(default_factory=set)
    ranges: dict[str, float] = field(default_factory=dict)
    needs: dict[str, float] = field(default_factory=dict)

    def take(self, ctx: RunContext, board: TaskBoard, slot: str | None = None) -> str | None:
        need = self.needs.get(slot, 0.0) if slot is not None else 0.0
        for rid in self.rovers:
            r = ctx.fleet.rovers[rid]
            if self.ranges.get(rid, math.inf) + RANGE_TOLERANCE < need:
                continue  # its battery cannot fly this flight
            if rid not in self.used and board.available(rid) and r.connected and not r.lost:
                self.used.add(rid)
                return rid
        return None


class Launcher:
    """Launches rovers for one deployment (see the module docstring)."""

    def __init__(self, ctx: RunContext, carrier: CarrierControl, board: TaskBoard) -> None:
        self.ctx = ctx
        self.carrier = carrier
        self.board = board
        self.uploaded: dict[str, tuple[int, str]] = {}  # rover -> (compiled plan, slot) it holds

    async def pre_upload(self, slot: RoverMission, plan_id: int) -> None:
        """Upload a slot's mission to its planned rover ahead of the stop (a spare may fly it)."""
        try:
            await upload(self.ctx, self.ctx.fleet.rovers[slot.rover], list(slot.items))
            self.uploaded[slot.rover] = (plan_id, slot.rover)
        except (ExecutionError, LinkError, TimeoutError) as exc:
            self.ctx.record(
                Ev.ROVER_FAILED,
                vehicle=slot.rover,
                text=f"upload failed ({exc}); a spare will fly {slot.task}",
            )

    async def launch(
        self, slot: RoverMission, plan_id: int, spares: Spares, go_at: float | None = None
    ) -> str | None:
        """Launch a rover for ``slot``'s task: armed at once, started at ``go_at`` (mission clock:
        when unloading ends) or at once; returns the rover that is clear of the deck (None: no
        rover left to fly it)."""
        task = slot.task or ""
        rid: str | None = slot.rover
        while rid is not None:
            await self.carrier.ready()  # no launches while the carrier is lost
            if not self.board.available(rid):
                rid = spares.take(self.ctx, self.board, slot.rover)
                continue
            v = self.ctx.fleet.rovers[rid]
            if not await self._on_deck(v):
                self.ctx.state.event(Ev.ROVER_SKIPPED, f"{rid}: not on the deck, a spare takes {task}", rid)
                rid = spares.take(self.ctx, self.board, slot.rover)
                continue
            armed, spare = await self._arm(v, slot, plan_id, spares)
            if not armed:
                rid = spare
                continue
            if not await self._lift_off(v, slot, go_at):
                rid = spares.take(self.ctx, self.board, slot.rover)
                continue
            return rid
        return None

    async def _on_deck(self, v: Vehicle) -> bool:
        # telemetry of rover and carrier may be of different moments
        if not rover_on_deck(self.ctx, v):
            with contextlib.suppress(TimeoutError):
                await v.wait_until(lambda v: rover_on_deck(self.ctx, v), DECK_CHECK_TIMEOUT, "on the deck")
        return rover_on_deck(self.ctx, v)

    async def _arm(
        self, v: Vehicle, slot: RoverMission, plan_id: int, spares: Spares
    ) -> tuple[bool, str | None]:
        """Upload (when the rover does not hold this slot's mission) and arm. Returns (True, the
        rover) or (False, the spare that takes over, None when none is left)."""
        rid, task, st = v.name, slot.task or "", self.ctx.state
        try:
            if self.uploaded.get(rid) != (plan_id, slot.rover):
                await upload(self.ctx, v, list(slot.items))
                self.uploaded[rid] = (plan_id, slot.rover)
            await self.ctx.commit(Ev.LAUNCH, vehicle=rid, task=task, stop=slot.stop + 1)
            await self.ctx.command(v, "arm", v.arm())
            return True, rid
        except CommandRejected as exc:
            self.board.refused.add(rid)
            st.set_state(rid, VehicleStatus.REFUSED)
            spare = spares.take(self.ctx, self.board, slot.rover)
            reason = exc.reason or exc.ack.result_name
            then = f"spare {spare} takes {task}" if spare else f"no spare left for {task}"
            st.event(
                Ev.ROVER_REFUSED,
                f"{rid}: refused to arm ({reason}); {then}",
                rid,
                reason=reason,
                spare=spare,
                task=task,
            )
            if spare is not None:
                self.board.substitutions.append({"refused": rid, "spare": spare, "task": task})
            return False, spare
        except (ExecutionError, LinkError, TimeoutError) as exc:
            spare = spares.take(self.ctx, self.board, slot.rover)
            st.event(
                Ev.ROVER_FAILED,
                f"{rid}: {exc}; " + (f"spare {spare} takes {task}" if spare else f"no spare left for {task}"),
                rid,
                spare=spare,
                task=task,
            )
            return False, spare

    async def _lift_off(self, v: Vehicle, slot: RoverMission, go_at: float | None) -> bool:
        """Start ``v`` (at ``go_at``) and wait until it is clear of the deck: its take-off item
        done or above CLEAR_HEIGHT (the time model's ``takeoff_time``)."""
        tk, ctx = takeoff_seq(slot), self.ctx
        if go_at is not None:
            await ctx.sleep_mission(max(go_at - ctx.clock(), 0.0))
        timeout = max(LIFTOFF_TIMEOUT, 3.0 * ctx.mission.rovers.takeoff_time)
        try:
            await ctx.command(v, "start_mission", v.start_mission())
            # a task on the ground may be left again before a position shows it
            await ctx.wait_for(
                v,
                lambda v: (
                    (v.height or 0.0) > CLEAR_HEIGHT
                    or tk in v.items_reached
                    or (v.mission_current or -1) > tk
                ),
                timeout,
                "lift-off",
            )
            return True
        except (CommandRejected, LinkError, TimeoutError) as exc:
            self.ctx.state.event(
                Ev.ROVER_FAILED, f"{v.name}: did not take off ({exc})", v.name, task=slot.task
            )
            with contextlib.suppress(CommandRejected, LinkError, TimeoutError):
                await v.disarm()
            return False


__all__ = [
    "AIRBORNE_HEIGHT",
    "CLEAR_HEIGHT",
    "DECK_CHECK_TIMEOUT",
    "Launcher",
    "Spares",
    "flight_path",
    "rover_on_deck",
    "takeoff_seq",
]
