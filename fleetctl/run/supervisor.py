"""Supervision: telemetry and operator input turned into events the executor replans on.

:class:`Supervisor` watches a connected :class:`fleetctl.mavlink.fleet.Fleet` and puts
:class:`SupervisorEvent` s on an :class:`asyncio.Queue` that the executor consumes:

* ``lost`` / ``back``: nothing heard for ``links.heartbeat_timeout`` (the vehicle proxy's timer),
  and the first heartbeat after that;
* ``battery_low``: a rover's battery at or below the reserve the plan assumed (``rovers.reserve``),
  once per rover;
* ``off_course``: an airborne rover farther than :data:`OFF_COURSE_M` from the path it was given
  (:meth:`Supervisor.expect`), once until it is back within half of it;
* ``tasks``: tasks added/removed - from the running mission file (its ``tasks:`` are re-read when
  the file's mtime changes, polled every :data:`FILE_POLL_S` s, and re-validated with
  :mod:`fleetctl.mission`; an invalid edit is rejected with a ``task_change_rejected`` event and
  the running plan is kept) or from :meth:`fleetctl.run.executor.Executor.submit_task_change` (the
  MQTT bus calls it).

Every event carries ``t``: the ``time.monotonic()`` of its detection, from which the executor
measures the replan latency (event -> first new command sent).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fleetctl.aio import cancel_and_wait
from fleetctl.mavlink.fleet import Fleet
from fleetctl.mavlink.vehicle import VehicleEvent, VehicleEventKind
from fleetctl.mission import Mission, MissionError, load_mission
from fleetctl.mission.limits import MAX_FILE_BYTES
from fleetctl.mission.model import TaskWork
from fleetctl.run.kinds import Ev
from fleetctl.run.state import FleetState
from planners.core.problem import Task, Vec3

log = logging.getLogger(__name__)

OFF_COURSE_M = 6.0  # m (3D) from the given path: off course
FILE_POLL_S = 0.5  # wall s between looks at the mission file's mtime
CHECK_S = 0.2  # wall s between battery / course checks


@dataclass
class SupervisorEvent:
    kind: str  # lost | back | battery_low | off_course | tasks
    vehicle: str | None = None
    t: float = field(default_factory=time.monotonic)
    add: tuple[Task, ...] = ()
    remove: tuple[str, ...] = ()
    source: str = ""
    data: dict[str, Any] = field(default_factory=dict)
    work: dict[str, TaskWork] = field(default_factory=dict)  # an added task's work, when the change gives it
    retime: dict[str, TaskWork] = field(default_factory=dict)  # a kept task's new work (a long operation)


def distance_to_path(p: Sequence[float], path: Sequence[Vec3]) -> float:
    """3D distance from ``p`` to the polyline ``path``."""
    if not path:
        return math.inf
    if len(path) == 1:
        return math.dist(p, path[0])
    best = math.inf
    for a, b in zip(path, path[1:], strict=False):
        ab = [b[i] - a[i] for i in range(3)]
        ap = [p[i] - a[i] for i in range(3)]
        den = sum(c * c for c in ab)
        u = 0.0 if den <= 0 else max(0.0, min(1.0, sum(ab[i] * ap[i] for i in range(3)) / den))
        q = [a[i] + u * ab[i] for i in range(3)]
        best = min(best, math.dist(p, q))
    return best


def validate_task_change(current: dict[str, Task], add: Sequence[Task], remove: Sequence[str],
                         deploy_range: float) -> str | None:
    """Why a task change cannot be applied (None = it can): unknown ids to remove, duplicate ids,
    tasks out of every rover's reach (higher than ``deploy_range``)."""
    unknown = [r for r in remove if r not in current]
    if unknown:
        return f"cannot remove unknown task(s) {', '.join(unknown)}"
    ids = [t.id for t in add]
    dup = sorted({i for i in ids if ids.count(i) > 1 or (i in current and i not in remove)})
    if dup:
        return f"task id(s) {', '.join(dup)} already exist; give new tasks new ids"
    for t in add:
        if len(t.position) != 3 or not all(math.isfinite(c) for c in t.position):
            return f"task {t.id}: position must be [x, y, z] in metres"
        if t.position[2] < 0 or t.position[2] > deploy_range:
            return (f"task {t.id}: height {t.position[2]:g} m is out of reach (0..deploy_range "
                    f"{deploy_range:g} m)")
    return None


class Supervisor:
    """Turns telemetry and task edits into :class:`SupervisorEvent` s on :attr:`queue`.

    ``tasks``: a callable giving the live task set (id -> Task) to diff file edits against."""

    def __init__(self, mission: Mission, fleet: Fleet, state: FleetState, *,
                 tasks: Callable[[], dict[str, Task]], record: Callable[..., None] | None = None,
                 watch_file: bool = True) -> None:
        self.mission = mission
        self.fleet = fleet
        self.state = state
        self.tasks = tasks
        self.record = record or (lambda kind, **data: None)
        self.queue: asyncio.Queue[SupervisorEvent] = asyncio.Queue()
        self.paths: dict[str, list[Vec3]] = {}
        self._low: set[str] = set()
        self._off: set[str] = set()
        self._bg: list[asyncio.Task[None]] = []
        self._unlisten: Callable[[], None] | None = None
        self._watch_file = watch_file and mission.path is not None
        self._mtime: float | None = None
        self._work = {t.id: mission.task_work(t.id) for t in mission.tasks}  # each task's work, as last read

    # -- lifecycle ---------------------------------------------------------------------------------
    def start(self) -> None:
        if self._unlisten is not None:
            return
        self._unlisten = self.fleet.add_listener(self._on_vehicle_event)
        self._bg.append(asyncio.create_task(self._check_loop(), name="supervisor checks"))
        if self._watch_file:
            with contextlib.suppress(OSError):
                self._mtime = Path(self.mission.path).stat().st_mtime_ns  # type: ignore[arg-type]
            self._bg.append(asyncio.create_task(self._file_loop(), name="supervisor mission file"))

    async def close(self) -> None:
        if self._unlisten is not None:
            self._unlisten()
            self._unlisten = None
        bg, self._bg = self._bg, []
        await cancel_and_wait(*bg)

    def put(self, ev: SupervisorEvent) -> None:
        self.queue.put_nowait(ev)

    # -- expectations ------------------------------------------------------------------------------
    def expect(self, rover: str, path: Sequence[Vec3] | None) -> None:
        """The path ``rover`` was sent along (None: no expectation, e.g. holding or landed)."""
        if path is None:
            self.paths.pop(rover, None)
        else:
            self.paths[rover] = [tuple(map(float, p)) for p in path]  # type: ignore[misc]
        self._off.discard(rover)

    # -- sources -----------------------------------------------------------------------------------
    def _on_vehicle_event(self, ev: VehicleEvent) -> None:
        if ev.kind in (VehicleEventKind.LOST, VehicleEventKind.BACK):
            self.put(SupervisorEvent(ev.kind, ev.vehicle, data=dict(ev.data)))

    async def _check_loop(self) -> None:
        reserve = self.mission.rovers.reserve
        while True:
            await asyncio.sleep(CHECK_S)
            for rid, v in self.fleet.rovers.items():
                if not v.connected or v.lost:
                    continue
                pct = v.battery_pct
                if pct is not None and pct / 100.0 <= reserve and rid not in self._low:
                    self._low.add(rid)
                    self.put(SupervisorEvent("battery_low", rid, data={"battery_pct": pct,
                                                                       "reserve": reserve}))
                path = self.paths.get(rid)
                p = v.enu
                if path is None or p is None:
                    continue
                d = distance_to_path(p, path)
                if d > OFF_COURSE_M and rid not in self._off:
                    self._off.add(rid)
                    self.put(SupervisorEvent("off_course", rid, data={"distance": round(d, 2),
                                                                      "position": p}))
                elif d < OFF_COURSE_M / 2:
                    self._off.discard(rid)

    async def _file_loop(self) -> None:
        """Poll the mission file; never dies: any problem with one edit rejects that edit (the
        running plan is kept) and the next edit is looked at as usual."""
        path = Path(self.mission.path)  # type: ignore[arg-type]
        while True:
            await asyncio.sleep(FILE_POLL_S)
            try:
                await self._file_check(path)
            except asyncio.CancelledError:
                raise
            except Exception as exc:  # noqa: BLE001 - the watcher must outlive any bad edit
                log.exception("mission file %s: edit not applied", path)
                self.reject(f"{path}: the edit could not be read ({type(exc).__name__}: {exc}); "
                            "fix the file and save it again", source=f"file {path}")

    async def _file_check(self, path: Path) -> None:
        try:
            st = await asyncio.to_thread(path.stat)
        except OSError:
            return
        if st.st_mtime_ns == self._mtime:
            return
        self._mtime = st.st_mtime_ns
        if st.st_size > MAX_FILE_BYTES:  # refused before reading it
            self.reject(f"{path}: the mission file is larger than {MAX_FILE_BYTES} bytes; edit not read",
                        source=f"file {path}")
            return
        try:
            new = await asyncio.to_thread(load_mission, path)
        except MissionError as exc:
            self.reject(f"{exc}", source=f"file {path}")
            return
        current = self.tasks()
        newt = {t.id: t for t in new.tasks}
        remove = tuple(i for i, t in current.items()
                       if i not in newt or tuple(newt[i].position) != tuple(t.position))
        add = tuple(t for i, t in newt.items() if i not in current or i in remove)
        retime = {i: new.task_work(i) for i in newt if i in current and i not in remove
                  and self.mission.operation and new.task_work(i) != self._work.get(i)}
        self._work.update({i: new.task_work(i) for i in newt})
        if add or remove or retime:
            self.put(SupervisorEvent("tasks", None, add=add, remove=remove, source=f"file {path}",
                                     work={t.id: new.task_work(t.id) for t in add}, retime=retime))

    def reject(self, why: str, source: str) -> None:
        """An invalid task change: say so; the running plan is kept."""
        self.state.event(Ev.TASK_CHANGE_REJECTED, f"task change from {source} rejected, plan kept: {why}",
                         None, source=source, reason=why)


__all__ = ["CHECK_S", "FILE_POLL_S", "OFF_COURSE_M", "Supervisor", "SupervisorEvent", "distance_to_path",
           "validate_task_change"]
