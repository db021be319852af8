"""Mission keys of a long operation (docs/mission-file.md, docs/operations.md): each task's work
(``tasks[].duration``, ``tasks[].work``, default ``dwell`` and ``rovers.work``) and the checks that
make an operation plannable (one carrier, every hovered task within a battery)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, NoReturn

from fleetctl.mission.model import TaskWork
from planners.core.problem import Task

WORK_MODES = ("hover", "ground")  # how a rover works at a task: hovering (burns its battery) or landed

Fail = Callable[[tuple[str | int, ...], str], NoReturn]


def task_work(rows: Sequence[dict[str, Any]], dwell: float, default_work: str) -> tuple[TaskWork, ...]:
    """Each task's work: its ``duration`` (default the mission's ``dwell``) and its ``work`` mode
    (default ``rovers.work``)."""
    return tuple(TaskWork(dwell if t.get("duration") is None else float(t["duration"]),
                          (t.get("work") or default_work) == "ground") for t in rows)


def check_one_carrier(fail: Fail, d: dict[str, Any]) -> None:
    """An operation is planned for one carrier (checked before the teams' rovers are counted)."""
    if d["operation"] and d["carriers"] is not None and len(d["carriers"]) > 1:
        fail(("operation",), f"a long operation is planned for one carrier; the mission has "
                             f"{len(d['carriers'])} in 'carriers:' (keep one, or set operation: false)")


def check_operation(fail: Fail, d: dict[str, Any], tasks: Sequence[Task], work: Sequence[TaskWork],
                    endurance_range: float) -> None:
    """Every task worked hovering fits a battery above its reserve (the flights to and from it come
    on top: the planner says when those do not fit)."""
    if not d["operation"]:
        return
    r = d["rovers"]
    air = (1.0 - r["reserve"]) * endurance_range / r["max_speed"]  # s in the air above the reserve
    for i, (t, w) in enumerate(zip(tasks, work, strict=True)):
        if not w.ground and w.duration >= air:
            fail(("tasks", i, "duration"),
                 f"task {t.id!r} needs {w.duration:g} s of work hovering, but a full battery gives "
                 f"{air:.0f} s in the air above the reserve (rovers.endurance_range / max_speed × "
                 f"(1 − reserve)); shorten the task, work it landed (work: ground) or raise endurance_range")
