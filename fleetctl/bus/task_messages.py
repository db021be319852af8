"""Task messages from the bus (``P/tasks/add``, ``P/tasks/remove``, ``P/tasks/update``): decoded
within bounds and checked like the mission file before anything changes.

:func:`decode_task_json` reads a payload (size, nesting depth and JSON checked first, the
optional ``"force"`` flag taken out); :class:`TaskRules` turns the decoded message into the
change - new tasks with their work, task ids to remove, a task's new work - against the live task
set, by the mission loader (a new task is validated as if it were in the mission file), and says
when a valid change would make the mission absurd. Every refusal is a :class:`TaskMessageError`
whose text answers the sender (``P/errors``). No I/O here: :class:`fleetctl.bus.client.FleetBus`
subscribes, answers and hands the change to the controller.
"""

from __future__ import annotations

import copy
import json
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from fleetctl.bus.config import MAX_JSON_DEPTH, MAX_MESSAGE
from fleetctl.mission import MissionError, parse_mission
from fleetctl.mission.limits import FAR_FACTOR, MIN_EXTENT
from fleetctl.mission.model import TaskWork

if TYPE_CHECKING:
    from fleetctl.mission import Mission
    from planners.core.problem import Task

_JSON_STRING = re.compile(rb'"(?:[^"\\]|\\.)*"')
_BRACKETS = re.compile(rb"[\[\]{}]")


class TaskMessageError(ValueError):
    """A task message that changes nothing; the text goes to ``<prefix>/errors``."""


def json_depth(payload: bytes) -> int:
    """The deepest nesting of lists/objects in a JSON text (brackets inside strings ignored);
    linear, no recursion, so it can be checked before ``json.loads`` (which recurses)."""
    depth = deepest = 0
    for m in _BRACKETS.finditer(_JSON_STRING.sub(b'""', payload)):
        if m.group() in (b"[", b"{"):
            depth += 1
            deepest = max(deepest, depth)
        else:
            depth -= 1
    return deepest


def bounded_json(payload: bytes, max_bytes: int, max_depth: int, error: type[ValueError],
                 nothing_changed: str = "") -> Any:
    """``payload`` decoded, once it is at most ``max_bytes`` long and nested at most ``max_depth``
    deep (checked before ``json.loads``, which recurses); ``error`` otherwise (``nothing_changed``
    ends the depth message)."""
    if len(payload) > max_bytes:
        raise error(f"message of {len(payload)} bytes is larger than {max_bytes}")
    depth = json_depth(payload)
    if depth > max_depth:
        raise error(f"JSON nested {depth} levels deep (at most {max_depth}){nothing_changed}")
    try:
        return json.loads(payload)
    except (ValueError, UnicodeDecodeError, RecursionError) as exc:
        raise error(f"not JSON: {exc}") from None


def decode_task_json(payload: bytes) -> tuple[Any, bool]:
    """A task message's JSON and its ``force`` flag, once the message is within the size
    (``MAX_MESSAGE``) and nesting (``MAX_JSON_DEPTH``) limits; :class:`TaskMessageError` otherwise."""
    data = bounded_json(payload, MAX_MESSAGE, MAX_JSON_DEPTH, TaskMessageError, "; nothing changed")
    force = False
    if isinstance(data, dict) and "force" in data:
        force = data.pop("force")
        if not isinstance(force, bool):
            raise TaskMessageError('"force" must be true or false')
    return data, force


def _entries(data: Any) -> list[Any]:
    """``{"tasks": [...]}``, a list, or one entry: the list of entries."""
    if isinstance(data, dict) and "tasks" in data and set(data) == {"tasks"}:
        data = data["tasks"]
    return data if isinstance(data, list) else [data]


@dataclass
class TaskRules:
    """The checks of task changes for one mission. ``current`` gives the live task set (the
    controller's: it changes with replans), ``work_of`` a task's work now (a long operation's
    changes included)."""

    mission: Mission
    current: Callable[[], list[Task]]
    work_of: Callable[[str], TaskWork]

    def add(self, data: Any, source: str) -> tuple[list[Task], dict[str, TaskWork]]:
        """The tasks of an add message and each one's work (its optional ``duration`` and ``work``;
        default the mission's ``dwell`` and ``rovers.work``), checked by the mission loader
        against the current task set and the fleet (ids unique, heights within the deploy range,
        outside obstacles, a rover each)."""
        entries = _entries(data)
        if not entries:
            raise TaskMessageError('no tasks given; send {"tasks": [{"id": ..., "position": [x, y, z]}]}')
        if not all(isinstance(e, dict) for e in entries):
            raise TaskMessageError('expected a task {"id", "position": [x, y, z]} or a list of them')
        current = self.current()
        known = {t.id for t in current}
        for i, e in enumerate(entries):
            if isinstance(e.get("id"), str) and e["id"] in known:
                raise TaskMessageError(f"tasks[{i}].id: task {e['id']!r} already exists; use a new id")
        raw = self._raw()
        raw["tasks"] = list(entries) + [{"id": t.id, "position": [float(c) for c in t.position]}
                                        for t in current]
        if "carriers" not in raw:  # (a carriers: list gives every fleet's count itself)
            rovers = dict(raw.get("rovers") or {})
            rovers.pop("fleet", None)  # the fleet is fixed: spell out its units
            rovers["units"] = [{"id": u.id, "sysid": u.sysid} | ({} if u.connection is None else
                                                                 {"connection": u.connection})
                               for u in self.mission.rovers.units]
            raw["rovers"] = rovers
        m = self._load(raw, source)
        added = list(m.tasks[: len(entries)])
        return added, {t.id: m.task_work(t.id) for t in added}

    def update(self, data: Any, source: str) -> dict[str, TaskWork]:
        """A long operation's ``tasks/update`` message: each named task's new work (``duration``,
        ``work``; what it does not give stays as it is), checked by the mission loader."""
        if not self.mission.operation:
            raise TaskMessageError("tasks/update changes a task's work in a long operation (operation: "
                                   "true); this mission is not one: nothing changed")
        entries = _entries(data)
        if not entries or not all(isinstance(e, dict) and isinstance(e.get("id"), str) for e in entries):
            raise TaskMessageError('expected {"tasks": [{"id": "t3", "duration": 60}]} (an id and the work '
                                   'to change: "duration" in s, "work": "hover" or "ground")')
        current = {t.id: t for t in self.current()}
        for i, e in enumerate(entries):
            if e["id"] not in current:
                raise TaskMessageError(f"tasks[{i}].id: unknown task {e['id']!r}; current tasks: "
                                       f"{', '.join(sorted(current)) or 'none'}")
            if not set(e) - {"id"} or set(e) - {"id", "duration", "work"}:
                raise TaskMessageError(f'tasks[{i}]: give "duration" and/or "work" (and nothing else) with '
                                       f"the id")
        raw = self._raw()
        raw["tasks"] = [dict(e) for e in entries]
        for e in raw["tasks"]:
            e["position"] = [float(c) for c in current[e["id"]].position]
            old = self.work_of(e["id"])
            e.setdefault("duration", old.duration)
            e.setdefault("work", "ground" if old.ground else "hover")
        m = self._load(raw, source)
        return {t.id: m.task_work(t.id) for t in m.tasks}

    def remove(self, data: Any) -> list[str]:
        """The task ids of a remove message (``{"tasks": [...]}``, ``{"id": ...}``, a list or one
        id), each a current task."""
        if isinstance(data, dict) and set(data) in ({"tasks"}, {"id"}):
            data = data.get("tasks", data.get("id"))
        ids = data if isinstance(data, list) else [data]
        if not ids or not all(isinstance(i, str) and i.strip() for i in ids):
            raise TaskMessageError('expected {"tasks": ["t1", ...]} (task ids as non-empty strings)')
        known = {t.id for t in self.current()}
        unknown = [i for i in ids if i not in known]
        if unknown:
            raise TaskMessageError(f"unknown task id(s) {', '.join(map(repr, unknown))}; "
                                   f"current tasks: {', '.join(sorted(known)) or 'none'}")
        return list(dict.fromkeys(ids))

    def absurd(self, add: list[Task], remove: list[str]) -> str | None:
        """Why a valid change would make the mission absurd (None: it does not). Tasks outside
        ``bounds`` are refused by the mission checks already; without bounds, a new task farther
        than FAR_FACTOR x the mission's extent (largest carrier-start-to-task distance of the
        mission file, at least MIN_EXTENT m) from every remaining task and the carrier start is
        absurd, and so is removing every task."""
        current = self.current()
        keep = [t for t in current if t.id not in remove]
        if current and not keep and not add:
            return f"this would remove every task ({', '.join(sorted(t.id for t in current))})"
        if not add:
            return None
        start = (float(self.mission.carrier.position[0]), float(self.mission.carrier.position[1]))
        extent = max([MIN_EXTENT] + [math.dist(start, t.position[:2]) for t in self.mission.tasks])
        anchors = [start] + [tuple(t.position[:2]) for t in keep]
        for t in add:
            d = min(math.dist(t.position[:2], a) for a in anchors)
            if d > FAR_FACTOR * extent:
                return (f"task {t.id!r} at ({t.position[0]:.0f}, {t.position[1]:.0f}) is {d:.0f} m from the "
                        f"nearest task or the carrier start, more than {FAR_FACTOR:g} x the mission's "
                        f"extent of {extent:.0f} m; check its coordinates")
        return None

    def _raw(self) -> dict[str, Any]:
        """The mission file's data to check a change with: no MQTT section, obstacles as loaded
        (no file I/O here)."""
        raw = copy.deepcopy(self.mission.raw)
        raw.pop("mqtt", None)
        if isinstance(raw.get("obstacles"), dict):  # {file: PATH}
            raw["obstacles"] = [[list(v) for v in poly] for poly in self.mission.obstacles]
        return raw

    @staticmethod
    def _load(raw: dict[str, Any], source: str) -> Mission:
        try:
            return parse_mission(raw, f"mqtt {source}")
        except MissionError as exc:
            raise TaskMessageError(str(exc)) from None


__all__ = ["TaskMessageError", "TaskRules", "bounded_json", "decode_task_json", "json_depth"]
