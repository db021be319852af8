"""The names of a run: vehicle states, phases, journal/event kinds and supervisor event kinds.

:class:`Ev` is defined in :mod:`fleetctl.kinds` (the bus writes journal records too) and re-exported here.

Each is a :class:`~enum.StrEnum` whose values are the strings the journal, the summary, the MQTT
bus and the views have always used, so ``json.dumps`` writes them unchanged.
"""

from __future__ import annotations

from enum import StrEnum

from fleetctl.kinds import Ev


class VehicleStatus(StrEnum):
    """What the controller thinks a vehicle is doing (``FleetState.vehicles[id].state``)."""

    ON_DECK = "on_deck"
    CLIMBING = "climbing"
    EN_ROUTE = "en_route"
    ON_TASK = "on_task"
    RETURNING = "returning"
    WAITING = "waiting"  # a rover waiting for its timed release (collection)
    LANDED = "landed"
    LOADED = "loaded"
    LOST = "lost"
    REFUSED = "refused"
    IDLE = "idle"  # carrier before/after its route
    DRIVING = "driving"
    HOLDING = "holding"  # carrier waiting at a stop
    UNKNOWN = "unknown"


class Phase(StrEnum):
    """The run's phase (``FleetState.phase``, the bus status, the live view)."""

    CONNECT = "connect"
    PLAN = "plan"
    DEPLOY = "deploy"
    DWELL = "dwell"
    COLLECT = "collect"
    OPERATION = "operation"  # a long operation: sorties, pick-ups and swaps
    DONE = "done"
    FAILED = "failed"
    INTERRUPTED = "interrupted"


class Watch(StrEnum):
    """Kinds of :class:`fleetctl.run.supervisor.SupervisorEvent`."""

    LOST = "lost"
    BACK = "back"
    BATTERY_LOW = "battery_low"
    OFF_COURSE = "off_course"
    TASKS = "tasks"
    STRANDED = "stranded"  # a flying rover that will not reach its task (battery empty, down elsewhere)
    REASSIGN = "reassign"  # a lost rover's grace (links.reassign_after) is over


PHASES = ("deploy", "dwell", "collect")  # the phases of a run, in order


def phases_of(command: str) -> list[str]:
    """The phases ``command`` (``deploy`` | ``collect`` | ``run``) flies, in order."""
    return {"deploy": ["deploy"], "collect": ["collect"], "run": list(PHASES)}[command]


__all__ = ["PHASES", "Ev", "Phase", "VehicleStatus", "Watch", "phases_of"]
