"""The deck's swap station: one battery swap at a time, each ``carrier.swap_time`` mission
seconds, then the rover is told its battery is full (``Vehicle.swap_battery``)."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable

from fleetctl.mavlink.link import LinkError
from fleetctl.mavlink.vehicle import CommandRejected
from fleetctl.run.context import RunContext
from fleetctl.run.kinds import Ev
from fleetctl.run.operation.board import OperationBoard

DISARMED_WAIT = 10.0  # mission s for a rover loaded on the deck to be disarmed before its swap


class SwapStation:
    def __init__(self, ctx: RunContext, board: OperationBoard, now: Callable[[], float]) -> None:
        self.ctx, self.board, self.now = ctx, board, now
        self._free = asyncio.Lock()
        self.pending: dict[str, asyncio.Task[bool]] = {}  # rover -> its swap

    def start(self, rover: str) -> None:
        """Queue a swap for ``rover`` (on the deck)."""
        self.pending[rover] = self.ctx.spawn(self._swap(rover), f"swap {rover}")

    async def ready(self, rover: str, timeout: float) -> bool:
        """Wait (mission s) for ``rover``'s swap, if one is queued; False when it failed."""
        task = self.pending.pop(rover, None)
        if task is None:
            return True
        await self.ctx.wait_task(task, timeout)
        return task.done() and not task.cancelled() and task.result()

    async def _swap(self, rover: str) -> bool:
        ctx = self.ctx
        v = ctx.fleet.rovers[rover]
        async with self._free:
            start = self.now()
            with contextlib.suppress(TimeoutError):
                await ctx.wait_for(v, lambda v: not v.armed or v.lost, DISARMED_WAIT, "disarmed on the deck")
            if v.armed and not v.lost:
                with contextlib.suppress(CommandRejected, LinkError, TimeoutError):
                    await ctx.command(v, "disarm", v.disarm())
            await ctx.sleep_mission(ctx.mission.carrier.swap_time)
            try:
                await ctx.command(v, "swap_battery", v.swap_battery())
            except (CommandRejected, LinkError, TimeoutError) as exc:
                ctx.state.event(Ev.ROVER_FAILED, f"{rover}: battery swap failed ({exc})", rover)
                return False
        self.board.swaps.append((rover, self.now()))
        ctx.state.event(Ev.BATTERY_SWAPPED, f"{rover}: battery swapped ({self.now() - start:.1f} s)", rover,
                        started=round(start, 3), done=round(self.now(), 3))
        return True


__all__ = ["SwapStation"]
