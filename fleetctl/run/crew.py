"""Every mission flies through one :class:`Crew`: the run's lifecycle, written once.

A crew owns the :class:`~fleetctl.run.lifecycle.Session` of its run (the run folder and its
write-ahead journal, the mission clock, the embedded simulated fleet, the links, the exit status,
the summary) and goes through it in one order: the first records, the planners warmed, the
simulator (a collection scenario's batteries held), the links, the phases, and the way out - a
failure is recorded, an interruption (Ctrl-C, SIGTERM) holds every airborne rover, and in every
case the summary is written and everything closed in order.

What flies in it is the crew's :class:`Flight`, chosen by the mission's data
(:func:`fleetctl.run.flight.fly`):

* one team - :class:`~fleetctl.run.runner.TeamFlight`: the team's phases, in the run's records;
* several teams - :class:`~fleetctl.run.teams.coordinator.TeamsFlight`: the work shared between
  the teams and each team flown by a crew of one team on its share (its records in
  ``RUN/teams/<carrier>/<phase>/``; it borrows the run's simulator, links and bus).

A ``--team`` controller is a crew of one team whose flight also speaks to the other teams'
controllers (:class:`~fleetctl.run.teams.own_controller.TeamControllerRun`).
"""

from __future__ import annotations

import asyncio
import importlib
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Generic, Protocol, TypeVar

from fleetctl.mission import Mission
from fleetctl.run.context import ExecutionError
from fleetctl.run.lifecycle import OnSession, RunOptions, RunOutcome, Session

if TYPE_CHECKING:
    from fleetctl.mavlink.fleet import Fleet


class Flight(Protocol):
    """What flies in a :class:`Crew`, asked in this order (see the module docstring).

    ``warm_planners``: the crew imports the mission's planners before the fleet runs (a flight
    whose first plan is made while rovers hover; a run of several teams shares its work before
    any rover flies and each team's crew warms its own)."""

    warm_planners: bool

    async def begin(self) -> None:
        """The records are open: start the bus and write the run's first records
        (:meth:`~fleetctl.run.lifecycle.Session.begin_records`)."""

    def ready(self) -> None:
        """The simulated fleet (if any) runs and the mission clock is final; the links open next."""

    def emit(self, kind: str, text: str, vehicle: str | None = None, **data: Any) -> object:
        """An event of the run (a route conflict heard on the links)."""

    async def connected(self, fleet: Fleet) -> None:
        """The links are open: admit the vehicles, record them, take up a resumed run."""

    async def phases(self) -> None:
        """Fly the command's phases (those left, when resumed)."""

    def failed(self, error: str) -> None:
        """The run cannot go on (``error`` is the session's)."""

    async def cancelled(self) -> None:
        """The run was cancelled: airborne rovers hold (the session knows it was interrupted)."""

    async def end(self) -> dict[str, Any]:
        """The way out, whatever happened: background work stopped, the summary built."""

    async def close_bus(self) -> None:
        """Close (or let go of) the bus; called while the session closes."""


F = TypeVar("F", bound=Flight)


class Crew(OnSession, Generic[F]):
    """One run of ``command`` over ``mission``: its session and its flight (``flight(crew)``
    makes it; see the module docstring)."""

    def __init__(self, mission: Mission, command: str, opts: RunOptions,
                 flight: Callable[[Crew[F]], F]) -> None:
        self.session = Session(mission, command, opts)
        self.mission = mission
        self.command = command
        self.opts = opts
        self.journal = self.session.journal
        self.flight = flight(self)

    async def fly(self) -> RunOutcome:
        """The run from its first record to its summary (see the module docstring)."""
        s, f = self.session, self.flight
        s.open_records()
        await f.begin()
        try:
            if f.warm_planners:
                await self._warm_planners()
            await s.start_sim()
            s.pin_scenario_batteries(True)  # the flight lets them drain (after its connect or first plan)
            f.ready()
            await f.connected(await s.connect(f.emit))
            await f.phases()
        except ExecutionError as exc:
            s.error = str(exc)
            f.failed(s.error)
        except asyncio.CancelledError:
            s.was_interrupted()
            await f.cancelled()
        finally:
            summary = await f.end()
            s.write_summary(summary)
            await s.close(f.close_bus)
        return s.outcome(summary)

    async def _warm_planners(self) -> None:
        """Import the mission's planners (and the SciPy/shapely they need) before the fleet runs:
        a first plan would otherwise pay the import while rovers hover (seconds of battery on a
        fast simulated fleet)."""
        from planners import COLLECT_PLANNERS, DEPLOY_PLANNERS

        names: dict[str, dict[str, Any]] = {"deploy": DEPLOY_PLANNERS, "collect": COLLECT_PLANNERS}
        kinds = ("deploy", "collect") if self.command == "run" else (self.command,)
        loaders = [getattr(names[k].get(self.opts.planner or self.mission.planner_for(k)), "load", None)
                   for k in kinds]

        def warm() -> None:
            for load in loaders:
                if load is not None:
                    load()
            importlib.import_module("scipy.optimize")  # the placement searches use it on their first call
            # the re-sequencing of routes of more than 80 stops (planners.core.routing) uses its k-d tree:
            # its import costs some 280 ms of CPU, which a first plan or replan would otherwise pay
            importlib.import_module("scipy.spatial")

        await asyncio.to_thread(warm)


__all__ = ["Crew", "Flight"]
