"""A task far outside the others: probably a typo (a swapped coordinate, a lat/lon from elsewhere).

Not an error - a mission may have a remote task - but ``fleetctl plan`` and ``deploy`` print a
warning naming it. A task is *far* when its horizontal distance from the centroid of the *other*
tasks is more than ``OUTLIER_FACTOR`` times the median distance of those tasks from that centroid
and more than ``OUTLIER_MIN_DISTANCE`` metres (``fleetctl/mission/limits.py``). Leaving the task out
of its own reference keeps one far task from dragging the centroid (and the median) toward itself.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence

from fleetctl.mission.limits import OUTLIER_FACTOR, OUTLIER_MIN_DISTANCE
from fleetctl.mission.model import Mission
from planners.core.problem import Task

MIN_TASKS = 3  # with fewer there are no "others" to compare with


def far_tasks(tasks: Sequence[Task]) -> list[tuple[Task, float, float]]:
    """(task, its distance from the others' centroid, the others' median distance) of every far task."""
    if len(tasks) < MIN_TASKS:
        return []
    out = []
    for i, t in enumerate(tasks):
        others = [o.position[:2] for j, o in enumerate(tasks) if j != i]
        cx = sum(p[0] for p in others) / len(others)
        cy = sum(p[1] for p in others) / len(others)
        median = statistics.median(math.dist(p, (cx, cy)) for p in others)
        d = math.dist(t.position[:2], (cx, cy))
        if d > OUTLIER_FACTOR * median and d > OUTLIER_MIN_DISTANCE:
            out.append((t, d, median))
    return out


def far_task_warnings(mission: Mission) -> list[str]:
    """One line per far task of the mission, naming it and its distance."""
    return [f"task {t.id!r} at ({t.position[0]:.0f}, {t.position[1]:.0f}) is {d:.0f} m from the centroid "
            f"of the other tasks, more than {OUTLIER_FACTOR:g} x their median distance from it "
            f"({median:.0f} m); check its coordinates" for t, d, median in far_tasks(mission.tasks)]


__all__ = ["MIN_TASKS", "far_task_warnings", "far_tasks"]
