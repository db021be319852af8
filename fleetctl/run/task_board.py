"""The task board of a deployment: the one object that says where every task stands.

Each task of the live task set is *pooled* (no rover flies to it: not launched yet, or given back
after its rover was lost), *flying* (its rover is on the way), *reached* or *unserved* (with the
reason). The board also knows which rovers left the deck, which are unusable (lost on the deck)
or refused to arm, the task → rover assignment, the refused → spare substitutions, the tasks
added and removed while flying, and the rovers in the field without a task (to be collected).

Nothing here touches the fleet: the deploy phase changes the board, and ``fleetctl resume``
rebuilds one from the journal (:func:`fleetctl.run.resume.load_resumption`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

from planners.core.problem import Task


class TaskStatus(StrEnum):
    POOLED = "pooled"
    FLYING = "flying"
    REACHED = "reached"
    UNSERVED = "unserved"


@dataclass
class TaskEntry:
    task: Task
    status: TaskStatus = TaskStatus.POOLED
    rover: str | None = None  # flying: the rover on its way; reached: the rover that reached it
    reason: str | None = None  # why it is not (yet) reached
    flown: float | None = None  # reached: mission seconds since the deployment started


@dataclass
class TaskBoard:
    entries: dict[str, TaskEntry] = field(default_factory=dict)  # the live task set, in order
    launched: list[str] = field(default_factory=list)  # rovers that left the deck
    unusable: set[str] = field(default_factory=set)  # lost while on the deck
    refused: set[str] = field(default_factory=set)  # refused to arm
    assignment: dict[str, str] = field(default_factory=dict)  # task -> rover launched for it
    substitutions: list[dict[str, str]] = field(default_factory=list)  # refused rover -> spare
    added: list[str] = field(default_factory=list)
    removed: list[str] = field(default_factory=list)
    rejoined: list[str] = field(default_factory=list)  # rovers in the field without a task

    @classmethod
    def of(cls, tasks: list[Task] | tuple[Task, ...]) -> TaskBoard:
        return cls({t.id: TaskEntry(t) for t in tasks})

    # -- reading -----------------------------------------------------------------------------------
    @property
    def tasks(self) -> dict[str, Task]:
        return {tid: e.task for tid, e in self.entries.items()}

    def with_status(self, status: TaskStatus) -> list[str]:
        return [tid for tid, e in self.entries.items() if e.status == status]

    def pooled(self) -> list[Task]:
        return [e.task for e in self.entries.values() if e.status == TaskStatus.POOLED]

    def flying(self) -> dict[str, str]:
        """task -> rover flying to it."""
        return {
            tid: e.rover
            for tid, e in self.entries.items()
            if e.status == TaskStatus.FLYING and e.rover is not None
        }

    def airborne(self) -> list[str]:
        return list(self.flying().values())

    def task_of(self, rover: str) -> str | None:
        """The task ``rover`` is flying to, if any."""
        return next((t for t, r in self.flying().items() if r == rover), None)

    def is_pooled(self, tid: str) -> bool:
        e = self.entries.get(tid)
        return e is not None and e.status == TaskStatus.POOLED

    def unfinished(self) -> bool:
        return any(e.status in (TaskStatus.POOLED, TaskStatus.FLYING) for e in self.entries.values())

    def available(self, rover: str) -> bool:
        """May ``rover`` (on the deck) still be launched?"""
        return rover not in self.launched and rover not in self.unusable and rover not in self.refused

    # -- changes -----------------------------------------------------------------------------------
    def fly(self, tid: str, rover: str) -> None:
        e = self.entries[tid]
        e.status, e.rover = TaskStatus.FLYING, rover
        self.assignment[tid] = rover
        if rover not in self.launched:
            self.launched.append(rover)

    def unlaunch(self, rover: str) -> None:
        """``rover`` never left the deck after all (a launch cut short): it may fly again."""
        if rover in self.launched:
            self.launched.remove(rover)
        for tid, r in list(self.assignment.items()):
            e = self.entries.get(tid)
            if r == rover and e is not None and e.status != TaskStatus.REACHED:
                del self.assignment[tid]

    def reach(self, tid: str, flown: float) -> None:
        e = self.entries[tid]
        e.status, e.flown, e.reason = TaskStatus.REACHED, flown, None

    def give_back(self, tid: str, reason: str) -> str | None:
        """The task goes back to the pool (its rover will not reach it); returns that rover."""
        e = self.entries[tid]
        rover = e.rover if e.status == TaskStatus.FLYING else None
        e.status, e.rover, e.reason = TaskStatus.POOLED, None, reason
        return rover

    def unserve(self, tid: str, reason: str) -> None:
        e = self.entries[tid]
        e.status, e.rover, e.reason = TaskStatus.UNSERVED, None, reason

    def repool_unserved(self) -> list[str]:
        """Unserved tasks back into the pool (a rover came back to the deck); returns them."""
        back = self.with_status(TaskStatus.UNSERVED)
        for tid in back:
            self.entries[tid].status = TaskStatus.POOLED
        return back

    def add(self, task: Task) -> None:
        self.entries[task.id] = TaskEntry(task)
        self.added.append(task.id)

    def remove(self, tid: str) -> str | None:
        """Remove a task from the live set; returns the rover that was flying to it."""
        e = self.entries.pop(tid)
        self.removed.append(tid)
        self.assignment.pop(tid, None)
        return e.rover if e.status == TaskStatus.FLYING else None

    # -- the result --------------------------------------------------------------------------------
    def reached(self) -> dict[str, float]:
        return {tid: e.flown or 0.0 for tid, e in self.entries.items() if e.status == TaskStatus.REACHED}

    def unserved_reasons(self) -> dict[str, str]:
        return {
            tid: e.reason or "not reached"
            for tid, e in self.entries.items()
            if e.status != TaskStatus.REACHED
        }


__all__ = ["TaskBoard", "TaskEntry", "TaskStatus"]
