"""Replanning an operation from a live state (docs/operations.md, "Replanning"): the carrier stopped
where it is, rovers on the deck with what their batteries have left, rovers in the air with the
tasks their sortie still has (the first one possibly partly worked) and the battery they have flown.

:func:`seed` puts that state into a fresh :class:`~planners.operations.schedule.Schedule` (time 0
is now); the dispatch then schedules the tasks no rover has, picking the rovers in the air up as it
goes. Their sorties in the plan have ``launch_stop = -1`` (launched before the replan)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from planners.core.problem import Vec3
from planners.operations.plan import Sortie, Visit
from planners.operations.problem import OperationProblem, OpTask
from planners.operations.schedule import Airborne, Schedule, return_air
from planners.operations.timing import flight_time


@dataclass(frozen=True)
class InFlight:
    """A rover in the air (or landed at a task) on its sortie."""

    rover: str
    position: Vec3
    tasks: tuple[OpTask, ...]  # its work left, in order (durations: the work left of each)
    flown: float  # air seconds of its battery used so far
    on_ground: bool = False  # landed at a task worked on the ground
    worked_first: float = 0.0  # s of work its first task has had (a task left is done again in full)


@dataclass(frozen=True)
class LiveState:
    """The operation now: the carrier stopped at ``carrier`` heading ``heading``."""

    carrier: Vec3
    heading: float
    on_deck: dict[str, float] = field(default_factory=dict)  # rover -> air s of its battery used (0: full)
    in_flight: tuple[InFlight, ...] = ()


def seed(sch: Schedule, state: LiveState) -> None:
    """Make ``sch`` start from ``state`` (``sch`` fresh, for ``problem.rovers`` = every rover of the
    state, on the deck or in the air)."""
    sch.pos = (state.carrier[0], state.carrier[1], 0.0)
    sch.heading = state.heading
    for r, used in state.on_deck.items():
        sch.used[r] = used
    for f in state.in_flight:
        sch.ready.pop(f.rover, None)
        sch.used.pop(f.rover, None)
        sch.air[f.rover] = _airborne(sch.p, f)
        sch.sorties.append(sch.air[f.rover].sortie)


def _airborne(problem: OperationProblem, f: InFlight) -> Airborne:
    """A rover in the air as the schedule's :class:`Airborne`: its visits from now on."""
    t, here, ground, air, visits = 0.0, f.position, f.on_ground, 0.0, []
    for task in f.tasks:
        fly = flight_time(here, task.position, problem, ground and here != task.position)
        arrive = t + fly
        t = arrive + task.duration
        air += fly + (0.0 if task.ground else task.duration)
        visits.append(Visit(task.id, task.position, arrive, t, t, task.ground))
        here, ground = task.position, task.ground
    if not visits:  # no work left: it flies back from where it is
        visits.append(Visit("", here, 0.0, 0.0, 0.0, ground))
    s = Sortie(f.rover, -1, 0.0, 0.0, visits, battery_start=1.0 - f.flown / problem.endurance)
    return Airborne(s, here, t, ground, air, f.flown)


def air_needed(problem: OperationProblem, f: InFlight, stop: Vec3) -> float:
    """Air seconds a rover in the air still needs: the flights to its tasks left and their work
    (hovering), then the way back to touch-down at ``stop``, leaving its last task at once."""
    a = _airborne(problem, f)
    return a.air_to_end + return_air(a.last, a.ground, stop, problem)


def short_of_battery(problem: OperationProblem, f: InFlight, stop: Vec3, margin: float = 0.0) -> bool:
    """The rover's battery does not last for its work left and the way back to ``stop`` (with
    ``margin`` air seconds to spare)."""
    return f.flown + air_needed(problem, f, stop) + margin > problem.air_budget + 1e-9


def call_margin(problem: OperationProblem) -> float:
    """Air seconds a rover called back keeps for waiting to be picked up (the dispatch's margin)."""
    return 2.0 * (problem.carrier.deploy_stop_time + problem.carrier.collect_stop_time)


@dataclass(frozen=True)
class CallBack:
    """A live state with rovers called back early: each rover short of battery keeps the longest
    prefix of its tasks that its battery allows with the way back to the carrier where it stands
    and :func:`call_margin` (``keep=False``, or none fits: it comes back at once); the tasks it
    drops go to the others, with their full work."""

    state: LiveState
    dropped: tuple[OpTask, ...]
    called_back: dict[str, list[str]]  # rover -> the tasks dropped from its sortie


def call_back(problem: OperationProblem, state: LiveState, keep: bool = True) -> CallBack | None:
    """``state`` with the rovers short of battery called back (None: no rover is short)."""
    air, dropped, called = [], [], {}
    margin = call_margin(problem)
    for f in state.in_flight:
        if not f.tasks or not short_of_battery(problem, f, state.carrier, margin):
            air.append(f)
            continue
        k = len(f.tasks) - 1 if keep else 0
        while k > 0 and short_of_battery(problem, replace(f, tasks=f.tasks[:k]), state.carrier, margin):
            k -= 1
        air.append(replace(f, tasks=f.tasks[:k], worked_first=f.worked_first if k else 0.0))
        for i, t in enumerate(f.tasks[k:], start=k):
            dropped.append(replace(t, duration=t.duration + f.worked_first) if i == 0 else t)
        called[f.rover] = [t.id for t in f.tasks[k:]]
    if not called:
        return None
    return CallBack(replace(state, in_flight=tuple(air)), tuple(dropped), called)



def recovery(problem: OperationProblem,
             state: LiveState) -> tuple[OperationProblem, LiveState, dict[str, list[str]]]:
    """The rest of last resort, for a live state no plan keeping every reserve starts from (rovers
    that hovered while the controller was down, a battery lower than it read): nothing launched,
    each rover short of battery called back at once (:func:`call_back`, keeping none), the others on
    their tasks, and the reserve given up so that every rover can still come back. The problem, the
    state and the call-backs; the work no rover has waits for the replan made once they are aboard."""
    cb = call_back(problem, state, keep=False)
    live, called = (cb.state, cb.called_back) if cb is not None else (state, {})
    return replace(problem, tasks=(), reserve=0.0), live, called


__all__ = ["CallBack", "InFlight", "LiveState", "air_needed", "call_back", "call_margin", "recovery", "seed",
           "short_of_battery"]
