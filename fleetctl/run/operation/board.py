"""Where an operation stands: every sortie (a :class:`SortieStatus`), every task's work and who
worked it, the swaps done. Nothing here touches the fleet; the phase changes it."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from typing import TYPE_CHECKING

from fleetctl.run.state import OperationProgress, SortieAhead, SortieShown

if TYPE_CHECKING:
    from planners.operations import OperationPlan


class SortieStatus(StrEnum):
    PLANNED = "planned"
    FLYING = "flying"  # launched, working its tasks
    RETURNING = "returning"  # on its way back to its pick-up stop
    ABOARD = "aboard"  # landed and loaded
    LOST = "lost"  # its rover was lost in the air
    FAILED = "failed"  # it did not take off


@dataclass
class TaskWorkState:
    duration: float
    rover: str | None = None
    started: float | None = None  # mission s of the operation when the work began
    done: float | None = None  # ... when the firmware reported it done
    seen_start: bool = True  # False: it started while the controller was down (resume): started is a bound

    def worked(self, now: float) -> float:
        """Seconds of work so far: its duration once done (the firmware timed it; the seconds the
        controller saw between the two reports are the journal's ``worked``)."""
        if self.done is not None:
            return self.duration
        if self.started is None:
            return 0.0
        return min(now - self.started, self.duration)


@dataclass
class SortieEntry:
    index: int
    rover: str
    tasks: list[str]
    status: SortieStatus = SortieStatus.PLANNED
    launched: float | None = None
    aboard: float | None = None


@dataclass
class OperationBoard:
    tasks: dict[str, TaskWorkState] = field(default_factory=dict)
    sorties: list[SortieEntry] = field(default_factory=list)
    swaps: list[tuple[str, float]] = field(default_factory=list)  # (rover, mission s when done)
    lost: list[str] = field(default_factory=list)
    next_index: int = 0  # the next sortie's index (journalled: a resumed run goes on counting)

    def new_sortie(self, rover: str, tasks: list[str]) -> SortieEntry:
        entry = SortieEntry(self.next_index, rover, tasks)
        self.next_index += 1
        self.sorties.append(entry)
        return entry

    def restore(self, other: OperationBoard) -> None:
        """Take ``other``'s state (a resumed run's, rebuilt from its journal) in place."""
        self.tasks, self.sorties, self.swaps = other.tasks, other.sorties, other.swaps
        self.lost, self.next_index = other.lost, other.next_index

    def done(self) -> list[str]:
        return [t for t, w in self.tasks.items() if w.done is not None]

    def left(self) -> list[str]:
        return [t for t, w in self.tasks.items() if w.done is None]

    def progress(self, now: float, eta: float | None,
                 ahead: tuple[SortieAhead, ...] = ()) -> OperationProgress:
        """What the views show (``now``: operation s; ``eta``: mission s of the phase; ``ahead``: the
        plan's sorties not launched yet)."""
        out = sum(1 for s in self.sorties if s.status in (SortieStatus.FLYING, SortieStatus.RETURNING))
        back = sum(1 for s in self.sorties if s.status is SortieStatus.ABOARD)
        tasks = {t: (round(w.worked(now), 1), w.duration, w.rover, w.done is not None)
                 for t, w in self.tasks.items()}
        shown = tuple(SortieShown(s.index, s.rover, str(s.status), tuple(s.tasks)) for s in self.sorties
                      if s.status in (SortieStatus.FLYING, SortieStatus.RETURNING))
        return OperationProgress(out, back, len(self.sorties), tasks, eta, shown, ahead)

    def flying(self, rover: str) -> SortieEntry | None:
        return next((s for s in self.sorties if s.rover == rover
                     and s.status in (SortieStatus.FLYING, SortieStatus.RETURNING)), None)


def sorties_ahead(plan: OperationPlan, entries: dict[int, SortieEntry], at: float) -> tuple[SortieAhead, ...]:
    """The sorties of ``plan`` (``entries``: its sortie index -> board entry) still to take off, the
    next first; ``at``: where the flight is on the plan's clock (operation s since it was adopted,
    less the delay so far)."""
    ahead = []
    for i, entry in entries.items():
        s = plan.sorties[i]
        if entry.status is not SortieStatus.PLANNED or s.launch_stop < 0:
            continue
        launch = plan.stops[s.launch_stop].position
        pickup = plan.stops[s.pickup_stop].position if s.pickup_stop >= 0 else None
        ahead.append(SortieAhead(entry.index, entry.rover, tuple(entry.tasks), (launch[0], launch[1]),
                                 None if pickup is None else (pickup[0], pickup[1]),
                                 max(0.0, s.takeoff - at)))
    return tuple(sorted(ahead, key=lambda a: (a.takeoff_in, a.index)))


__all__ = ["OperationBoard", "SortieEntry", "SortieStatus", "TaskWorkState", "sorties_ahead"]
