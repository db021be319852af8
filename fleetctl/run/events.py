"""Waiting on the fleet while supervision events arrive.

A phase hands every :class:`~fleetctl.run.supervisor.SupervisorEvent` to a handler that updates
its state and answers whether the rest of the plan must be thrown away (a replan). :func:`race`
awaits one step of the plan (the carrier reaching a stop, ...) while doing that; :func:`drain`
hands over what is queued.
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from typing import TypeVar

from fleetctl.aio import cancel_and_wait
from fleetctl.run.context import RunContext
from fleetctl.run.kinds import Ev, Watch
from fleetctl.run.supervisor import SupervisorEvent
from fleetctl.run.vehicle_events import battery_low_text

T = TypeVar("T")

Handler = Callable[[SupervisorEvent], bool]  # True: replan


async def race(
    queue: asyncio.Queue[SupervisorEvent], aw: Awaitable[T], handle: Handler
) -> tuple[bool, T | None]:
    """Await ``aw`` while handing events to ``handle``; when ``handle`` returns True (replan),
    ``aw`` is cancelled and ``(False, None)`` returned, else ``(True, result)``."""
    task = asyncio.ensure_future(aw)
    getter: asyncio.Future[SupervisorEvent] | None = None
    try:
        while True:
            getter = asyncio.ensure_future(queue.get())
            done, _ = await asyncio.wait({task, getter}, return_when=asyncio.FIRST_COMPLETED)
            if getter in done:
                ev, getter = getter.result(), None
                if handle(ev):
                    return False, None
                continue
            return True, task.result()
    finally:
        await cancel_and_wait(task, getter)


def drain(queue: asyncio.Queue[SupervisorEvent], handle: Handler) -> bool:
    """Hand every queued event to ``handle``; True if one asks for a replan."""
    again = False
    while not queue.empty():
        again = handle(queue.get_nowait()) or again
    return again


async def next_event(
    queue: asyncio.Queue[SupervisorEvent], others: set[asyncio.Task[None]], timeout: float
) -> SupervisorEvent | None:
    """The next event, or None when one of ``others`` finished first (or ``timeout`` passed)."""
    getter = asyncio.ensure_future(queue.get())
    try:
        await asyncio.wait({getter, *others}, timeout=timeout, return_when=asyncio.FIRST_COMPLETED)
    finally:
        await cancel_and_wait(getter)
    if getter.done() and not getter.cancelled():
        return getter.result()
    return None


def announce_warning(ctx: RunContext, ev: SupervisorEvent) -> None:
    """Battery and course warnings: journalled and shown (they do not change the plan)."""
    rid = ev.vehicle
    if rid is None:
        return
    if ev.kind == Watch.BATTERY_LOW:
        ctx.state.event(
            Ev.BATTERY_LOW,
            battery_low_text(rid, ev.data.get("battery_pct", "?")),
            rid,
            **ev.data,
        )
    elif ev.kind == Watch.OFF_COURSE:
        ctx.state.event(
            Ev.OFF_COURSE, f"{rid}: off course ({ev.data.get('distance')} m from its path)", rid, **ev.data
        )


__all__ = ["Handler", "announce_warning", "drain", "next_event", "race"]
