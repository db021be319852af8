"""What every part of a flight shares: the mission, the live fleet, the state the views read, the
mission clock, the journal and the background tasks the run owns.

* **Clock.** ``clock()`` is the mission clock (simulated seconds on the embedded simulated fleet,
  the vehicles' own seconds on SITL firmware run faster than real time -
  :mod:`fleetctl.mavlink.vehicle_clock` -, else ``time.monotonic``). Every wait on the fleet is a deadline
  in mission time, :meth:`RunContext.late` (the planned duration from the live plan, times
  ``TIMEOUT_FACTOR``, plus ``TIMEOUT_MARGIN`` mission seconds), waited by :meth:`RunContext.wait_for`,
  so a mission takes the same decisions at any speed-up; :meth:`RunContext.wall` (that deadline in
  wall seconds, plus ``TIMEOUT_WALL``) is only the backstop for a mission clock that stops.
* **Journalled commands.** :meth:`RunContext.command` writes the command record to disk
  (write-ahead, :meth:`fleetctl.journal.Journal.commit`) *before* sending it, then records the
  acknowledgement; a pending replan's latency is measured at its first command.
* **Owned tasks.** :meth:`RunContext.spawn` starts a background task the context cancels in
  :meth:`RunContext.close`.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Awaitable, Callable, Coroutine
from typing import Any, Protocol, TypeVar

from fleetctl.aio import cancel_and_wait
from fleetctl.mavlink.fleet import Fleet
from fleetctl.mavlink.link import LinkError, MissionRejected
from fleetctl.mavlink.vehicle import CommandRejected, Vehicle
from fleetctl.mission import Mission
from fleetctl.run.kinds import Ev
from fleetctl.run.replan_record import ReplanTracker
from fleetctl.run.state import FleetState

log = logging.getLogger(__name__)

T = TypeVar("T")

TIMEOUT_FACTOR = 2.0  # a wait may take this many times its planned (mission) duration ...
TIMEOUT_MARGIN = 30.0  # ... plus this many mission seconds ...
TIMEOUT_WALL = 15.0  # wall s more before a wait gives up on a mission clock that stopped (backstop)
POLL_WALL = 0.05  # wall s at most between looks at the mission clock in a wait
REPORT_WAIT = 2.5  # wall s past a deadline for the vehicle's next status report (1 Hz, lossy) to show it
TELEMETRY_TIMEOUT = 10.0  # wall s to wait for first positions


class ExecutionError(Exception):
    """The mission cannot be flown (a rejected upload, no rovers on the deck, ...): the message
    says what happened and what to change."""


class Recorder(Protocol):
    def __call__(self, kind: str, **data: Any) -> None: ...


class Committer(Protocol):
    def __call__(self, kind: str, **data: Any) -> Awaitable[None]: ...


class RunContext:
    """The shared parts of one flight (see the module docstring)."""

    def __init__(
        self,
        mission: Mission,
        fleet: Fleet,
        state: FleetState,
        *,
        record: Recorder | None = None,
        commit: Committer | None = None,
        speedup: float = 1.0,
        clock: Callable[[], float] | None = None,
    ) -> None:
        self.mission = mission
        self.fleet = fleet
        self.state = state
        self.record: Recorder = record or (lambda kind, **data: None)
        self._commit = commit
        self.speedup = speedup
        self.clock = clock or time.monotonic
        self.replans = ReplanTracker(state, self.record)
        self._tasks: set[asyncio.Task[Any]] = set()
        state.mission_clock = self.clock

    # -- records -----------------------------------------------------------------------------------
    async def commit(self, kind: str, **data: Any) -> None:
        """Write a record and wait until it is on disk (when the journal can; else just write)."""
        if self._commit is not None:
            await self._commit(kind, **data)
        else:
            self.record(kind, **data)

    async def command(self, v: Vehicle, what: str, aw: Coroutine[Any, Any, T], **data: Any) -> T:
        """Send one command (``aw`` not yet started): journal it write-ahead, then its ack."""
        self.replans.on_command()
        try:
            await self.commit(Ev.COMMAND, vehicle=v.name, command=what, **data)
        except BaseException:
            aw.close()
            raise
        try:
            result = await aw
        except CommandRejected as exc:
            self.record(Ev.ACK, vehicle=v.name, command=what, result=exc.ack.result_name, reason=exc.reason)
            raise
        except MissionRejected as exc:
            self.record(Ev.ACK, vehicle=v.name, command=what, result=exc.result_name, reason=exc.reason)
            raise
        except (LinkError, TimeoutError) as exc:
            self.record(Ev.ACK, vehicle=v.name, command=what, result="timeout", error=str(exc))
            raise
        self.record(Ev.ACK, vehicle=v.name, command=what, result="MAV_RESULT_ACCEPTED")
        return result

    # -- time --------------------------------------------------------------------------------------
    def wall(self, mission_seconds: float) -> float:
        """Wall seconds a wait of ``mission_seconds`` may take (generous: see TIMEOUT_*)."""
        return (mission_seconds * TIMEOUT_FACTOR + TIMEOUT_MARGIN) / self.speedup + TIMEOUT_WALL

    def late(self, planned: float) -> float:
        """Mission seconds a wait on something planned to take ``planned`` mission seconds is given
        (the stated slack: ``TIMEOUT_FACTOR`` times it plus ``TIMEOUT_MARGIN``)."""
        return max(planned, 0.0) * TIMEOUT_FACTOR + TIMEOUT_MARGIN

    async def wait_for(self, v: Vehicle, predicate: Callable[[Vehicle], bool], mission_seconds: float,
                       what: str) -> None:
        """Return once ``predicate(v)`` holds (checked on every message of ``v``); ``TimeoutError``
        once ``mission_seconds`` of mission time have passed (a deadline on the mission clock, so
        the same at any speed-up) and ``REPORT_WAIT`` wall seconds more brought no report showing
        it (status messages come at ~1 Hz of wall time); :meth:`wall` of it is a backstop for a
        clock that stops."""
        start = self.clock()
        end = start + max(mission_seconds, 0.0)
        backstop = time.monotonic() + self.wall(mission_seconds)
        expired: float | None = None  # wall time the mission deadline passed
        while not predicate(v):
            left = end - self.clock()
            now = time.monotonic()
            if left <= 0.0 and expired is None:
                expired = now
            # past the deadline, the vehicle's next status report (sent on wall time) decides
            if (expired is not None and now - expired >= REPORT_WAIT) or now >= backstop:
                raise TimeoutError(f"{v.name} (sysid {v.sysid}): {what} not reached within "
                                   f"{end - start:.1f} s of mission time")
            with contextlib.suppress(TimeoutError):
                await v.wait_until(predicate, min(max(left / self.speedup, 0.005), POLL_WALL), what)

    async def wait_task(self, task: asyncio.Future[Any], mission_seconds: float) -> None:
        """Wait for ``task`` at most ``mission_seconds`` of mission time (no error after that)."""
        end = self.clock() + max(mission_seconds, 0.0)
        backstop = time.monotonic() + self.wall(mission_seconds)
        while not task.done() and (left := end - self.clock()) > 0 and time.monotonic() < backstop:
            await asyncio.wait({task}, timeout=min(max(left / self.speedup, 0.005), POLL_WALL))

    async def sleep_mission(self, seconds: float) -> None:
        """Sleep ``seconds`` of mission time (checked against the mission clock)."""
        end = self.clock() + seconds
        deadline = time.monotonic() + self.wall(seconds)
        while (left := end - self.clock()) > 0 and time.monotonic() < deadline:
            await asyncio.sleep(min(max(left / self.speedup, 0.005), 0.1))

    async def wait_telemetry(self) -> None:
        """Wait for positions (and landed states of rovers) of every connected vehicle."""
        carrier = self.fleet.carrier

        async def one(v: Vehicle) -> None:
            with contextlib.suppress(TimeoutError):
                await v.wait_until(
                    lambda v: v.enu is not None and (v is carrier or v.landed_state is not None),
                    TELEMETRY_TIMEOUT,
                    "first position",
                )

        await asyncio.gather(*(one(v) for v in self.fleet.vehicles.values() if v.connected and not v.lost))
        if carrier.enu is None:
            raise ExecutionError(
                f"{carrier.name}: no position from the carrier within "
                f"{TELEMETRY_TIMEOUT:g} s (is GPS available?)"
            )

    # -- owned background tasks --------------------------------------------------------------------
    def spawn(self, coro: Coroutine[Any, Any, T], name: str) -> asyncio.Task[T]:
        task = asyncio.ensure_future(coro)
        task.set_name(name)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return task

    async def close(self) -> None:
        """Cancel every background task (call on shutdown)."""
        await cancel_and_wait(*self._tasks)


__all__ = ["Committer", "ExecutionError", "Recorder", "RunContext"]
