"""The executor: one object that flies a mission's phases on a connected fleet.

It wires the parts of a run together - the :class:`~fleetctl.run.context.RunContext` (clock,
journalled commands, owned tasks), :class:`~fleetctl.run.carrier.CarrierControl`, the
:class:`~fleetctl.run.supervisor.Supervisor`, :class:`~fleetctl.run.planning.Planning` - and
runs a :class:`~fleetctl.run.deploy.DeployPhase` (on its
:class:`~fleetctl.run.task_board.TaskBoard`) or a :class:`~fleetctl.run.collect.CollectPhase`.
The runner (:mod:`fleetctl.run.runner`) builds one per run; the MQTT bus calls
:meth:`Executor.submit_task_change`.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any

from fleetctl.mavlink.fleet import Fleet
from fleetctl.mavlink.vehicle import Vehicle, VehicleEvent, VehicleEventKind
from fleetctl.mission import Mission
from fleetctl.mission.model import TaskWork
from fleetctl.run.carrier import CarrierControl
from fleetctl.run.collect import CollectPhase, ResumedCollect
from fleetctl.run.context import Committer, Recorder, RunContext
from fleetctl.run.deploy import DeployPhase, ResumedDeploy
from fleetctl.run.kinds import Ev, VehicleStatus, Watch
from fleetctl.run.launch import AIRBORNE_HEIGHT
from fleetctl.run.parts import PhaseParts
from fleetctl.run.planning import Planning
from fleetctl.run.results import PhaseResult
from fleetctl.run.state import FleetState
from fleetctl.run.supervisor import Supervisor, SupervisorEvent
from fleetctl.run.task_board import TaskBoard
from fleetctl.run.vehicle_events import tell_vehicle_event
from planners.core.plan import Plan
from planners.core.problem import Task

if TYPE_CHECKING:
    from fleetctl.run.operation import OperationPhase
    from fleetctl.run.operation.resume import OperationReplay

log = logging.getLogger(__name__)

HOLD_TIMEOUT = 5.0  # wall s for each vehicle's hold command on the way out


class Executor:
    """Flies a mission's deployment and collection on a connected fleet."""

    def __init__(
        self,
        mission: Mission,
        fleet: Fleet,
        state: FleetState,
        *,
        record: Recorder | None = None,
        commit: Committer | None = None,
        planner: str | None = None,
        speedup: float = 1.0,
        clock: Callable[[], float] | None = None,
        write_plan: Callable[[str, Plan], None] | None = None,
        board: TaskBoard | None = None,
    ) -> None:
        self.ctx = RunContext(
            mission, fleet, state, record=record, commit=commit, speedup=speedup, clock=clock
        )
        self.carrier = CarrierControl(self.ctx)
        self.board = board if board is not None else TaskBoard.of(mission.tasks)
        self.supervisor = Supervisor(
            mission, fleet, state, tasks=lambda: dict(self.board.tasks), record=self.ctx.record
        )
        self.planning = Planning(self.ctx, planner, write_plan)
        self.parts = PhaseParts(self.ctx, self.carrier, self.supervisor, self.planning)
        self.deploy_phase: DeployPhase | None = None
        self.collect_phase: CollectPhase | None = None
        self.operation_phase: OperationPhase | None = None
        self._unlisten = fleet.add_listener(self._on_vehicle_event)
        try:
            self._loop: asyncio.AbstractEventLoop | None = asyncio.get_running_loop()
        except RuntimeError:
            self._loop = None

    # -- phases ------------------------------------------------------------------------------------
    async def deploy(self, resumed: ResumedDeploy | None = None) -> PhaseResult:
        """Plan from the live state and fly the deployment (the board's pooled tasks), replanning
        on supervision events; ``resumed`` takes over an interrupted one."""
        self.deploy_phase = DeployPhase(self.parts, self.board, resumed)
        return await self.deploy_phase.run()

    async def collect(
        self, rover_ids: Iterable[str] | None = None, resumed: ResumedCollect | None = None
    ) -> PhaseResult:
        """Plan the collection of ``rover_ids`` (default: every connected rover not on the deck)
        from live positions and batteries and fly it; ``resumed`` takes over an interrupted one."""
        self.collect_phase = CollectPhase(self.parts, resumed)
        return await self.collect_phase.run(rover_ids)

    async def operate(self, write_plan: Callable[[str, dict[str, Any]], None] | None = None,
                      resumed: OperationReplay | None = None) -> PhaseResult:
        """Plan and fly a long operation (sorties, pick-ups, battery swaps; docs/operations.md), or
        (``resumed``) finish an interrupted one."""
        from fleetctl.run.operation import OperationPhase

        self.operation_phase = OperationPhase(self.parts, write_plan, self.board)
        if resumed is not None:
            return await self.operation_phase.resume(resumed)
        return await self.operation_phase.run()

    async def sleep_mission(self, seconds: float) -> None:
        await self.ctx.sleep_mission(seconds)

    # -- from outside ------------------------------------------------------------------------------
    def submit_task_change(self, add: list[Task], remove: list[str], source: str,
                           work: dict[str, TaskWork] | None = None,
                           retime: dict[str, TaskWork] | None = None) -> None:
        """Add and/or remove tasks of the running mission (``work``: an added task's duration and
        work mode, when the change gives them; ``retime``: a kept task's new work, a long operation's).
        Safe to call from the event loop or from another thread; applied by the running phase."""
        ev = SupervisorEvent(Watch.TASKS, None, add=tuple(add), remove=tuple(remove), source=source,
                             work=dict(work or {}), retime=dict(retime or {}))
        try:
            running: asyncio.AbstractEventLoop | None = asyncio.get_running_loop()
        except RuntimeError:
            running = None
        if self._loop is None or running is self._loop:
            self.supervisor.put(ev)
        else:
            self._loop.call_soon_threadsafe(self.supervisor.put, ev)

    def _on_vehicle_event(self, ev: VehicleEvent) -> None:
        if ev.kind == VehicleEventKind.LOST:
            self.ctx.state.set_state(ev.vehicle, VehicleStatus.LOST)
        tell_vehicle_event(ev, self.ctx.state.event, self.ctx.record)

    # -- the way out -------------------------------------------------------------------------------
    async def hold_airborne(self, timeout: float = HOLD_TIMEOUT) -> list[str]:
        """Command every airborne or armed rover (and the carrier) to hold where it is; returns who
        was told."""
        told: list[str] = []

        async def hold(v: Vehicle) -> None:
            try:
                async with asyncio.timeout(timeout):
                    await self.ctx.command(v, "hold", v.set_mode("HOLD"))
                told.append(v.name)
            except Exception as exc:  # noqa: BLE001 - best effort on the way out
                log.warning("%s: could not command hold: %s", v.name, exc)

        fleet = self.ctx.fleet
        # armed counts too: a rover caught between start_mission and lift-off would fly on
        targets = [v for v in fleet.rovers.values()
                   if v.connected and not v.lost and (v.armed or is_airborne(v))]
        c = fleet.carrier
        if c.connected and not c.lost and c.armed:
            targets.append(c)
        await asyncio.gather(*(hold(v) for v in targets))
        if told:
            self.ctx.state.event(Ev.HOLD, f"commanded to hold: {', '.join(told)}", None, vehicles=told)
        return told

    async def close(self) -> None:
        """Cancel every background task (call on shutdown)."""
        self._unlisten()
        await self.supervisor.close()
        await self.ctx.close()


def is_airborne(v: Vehicle) -> bool:
    return v.on_ground is False or (v.height or 0.0) > AIRBORNE_HEIGHT


__all__ = ["Executor", "is_airborne"]
