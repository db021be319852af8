"""A lower bound of any operation's end (every task worked, every rover back on the deck).

Each bound below holds for every plan in the time model of docs/time-model.md ("Operations"):

1. Per task: the carrier stops at least once before the task's rover leaves (``u + τ``); the rover
   flies at least from the launch height to the task's height, works, flies at least from the
   task's height to the approach height (taking off first from a ground task), touches down and is
   loaded (``λ + l``).
2. Work: the rover with the most work carries at least the mean of every task's work plus the
   shortest flight into it; before that it is launched (``u + τ``), after it it flies back and is
   landed and loaded: makespan ≥ u + τ + Σ_j (d_j + in_j) / n + min_j out_j + λ + l, n = the rovers
   that can be used (at most one per task).
3. Swaps: a sortie spends at most ``air_budget`` in the air, at least in_j (+ d_j hovering) per task,
   so the operation flies at least S = ⌈Σ_j air_j / air_budget⌉ sorties, and the rovers' first
   batteries last at most n_rovers of them: at least S − n_rovers swaps, one at a time:
   makespan ≥ (S − n_rovers) · swap_time + the work bound's first launch and last return.
"""

from __future__ import annotations

import math

from planners.operations.problem import OperationProblem, OpTask
from planners.operations.timing import flight_time


def _flight_in(task: OpTask, problem: OperationProblem) -> float:
    """Shortest flight into a task: from the nearest other task, or straight up from a stop below it."""
    h = problem.takeoff_height
    best = flight_time((task.position[0], task.position[1], h), task.position, problem)
    for other in problem.tasks:
        if other is not task:
            best = min(best, flight_time(other.position, task.position, problem))
    return best


def _flight_out(task: OpTask, problem: OperationProblem) -> float:
    below = (task.position[0], task.position[1], problem.approach_height)
    return flight_time(task.position, below, problem, task.ground)


def operation_lower_bound(problem: OperationProblem) -> float:
    if not problem.tasks:
        return 0.0
    c = problem.carrier
    launch, back = c.deploy_stop_time, c.collect_stop_time
    ins = [_flight_in(t, problem) for t in problem.tasks]
    outs = [_flight_out(t, problem) for t in problem.tasks]
    per_task = max(launch + i + t.duration + o + back
                   for t, i, o in zip(problem.tasks, ins, outs, strict=True))
    n = min(len(problem.rovers), len(problem.tasks))
    ends = launch + min(outs) + back
    work = ends + sum(t.duration + i for t, i in zip(problem.tasks, ins, strict=True)) / n
    air = sum(i + (0.0 if t.ground else t.duration) for t, i in zip(problem.tasks, ins, strict=True))
    sorties = math.ceil(air / problem.air_budget - 1e-9)
    swaps = ends + max(sorties - len(problem.rovers), 0) * problem.swap_time
    return max(per_task, work, swaps)
