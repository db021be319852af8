"""The run summary (``summary.json``, schema ``fleetctl.summary/1``): what the run achieved,
accounting for every task and every rover - also after an interruption, when it is built from
what the phases' boards saw, never from what the plan intended."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from fleetctl.mission import Mission
from fleetctl.run.kinds import VehicleStatus
from fleetctl.run.results import PhaseResult
from fleetctl.run.state import FleetState, VehicleState

SUMMARY_SCHEMA = "fleetctl.summary/1"
AIRBORNE_HEIGHT = 0.3  # m above home: a rover this high (or reporting in air) is airborne


@dataclass
class RunFacts:
    """What the summary is built from."""

    mission: Mission
    command: str  # deploy | collect | run
    results: dict[str, PhaseResult]
    state: FleetState
    error: str | None
    interrupted: bool
    journal_path: str
    dwell_planned: float | None = None  # run: the dwell asked for (the option, else the mission's)
    dwell_flown: float | None = None
    missing: dict[str, str] | None = None  # rovers that did not answer at connect -> why
    left_out: dict[str, str] | None = None  # rovers that failed preflight -> why
    mqtt: dict[str, Any] | None = None  # FleetBus.stats() (None: no bus)


def build_summary(f: RunFacts) -> dict[str, Any]:
    op = f.results.get("operation")  # a long operation: one phase that deploys and collects
    dep, col = (op, op) if op is not None else (f.results.get("deploy"), f.results.get("collect"))
    task_ids = list(dep.tasks_all) if dep is not None and dep.tasks_all else [t.id for t in f.mission.tasks]
    reached = [] if f.command == "collect" else (dep.tasks_reached if dep else [])
    unserved = [] if f.command == "collect" else [t for t in task_ids if t not in reached]
    complete = (
        not f.interrupted
        and f.error is None
        and (f.command == "collect" or (dep is not None and dep.complete))
        and (f.command == "deploy" or (col is not None and col.complete))
    )
    planned, flown = _makespans(f, dep, col, complete)
    order = list(f.state.vehicles)
    missing = f.missing or {}
    left_out = f.left_out or {}
    lost = sorted(
        {*(dep.rovers_lost if dep else []), *(col.rovers_lost if col else []), *missing, *left_out}
        - set(col.rovers_loaded if col else []),
        key=lambda r: order.index(r) if r in order else 0,
    )
    out: dict[str, Any] = {
        "schema": SUMMARY_SCHEMA,
        "mission": f.mission.name,
        "phase": f.command,
        "result": "complete" if complete else ("interrupted" if f.interrupted else "incomplete"),
        "tasks_reached": reached,
        "tasks_done": _tasks_done(f, op, reached, complete),
        "tasks_unserved": unserved,
        "rovers_loaded": col.rovers_loaded if col else [],
        "rovers_lost": lost,
        "makespan_planned": None if planned is None else round(planned, 3),
        "makespan_flown": None if flown is None else round(flown, 3),
        "rovers_lost_reasons": {r: left_out[r] if r in left_out else _lost_reason(r, missing, f.state)
                                for r in lost},
        "link": dict(f.state.link),
        "mqtt": f.mqtt,
        "replans": f.state.replans,
        "journal": f.journal_path,
    }
    out.update(_accounting(f, dep, col, unserved, lost))
    if col is not None:
        out["rovers_unreachable"] = col.rovers_unreachable
        out["rovers_let_go"] = dict(col.rovers_let_go)
        out["rovers_not_loaded_reasons"] = dict(col.rovers_failed)
    if dep is not None:
        out["assignment"] = dep.assignment
        out["substitutions"] = dep.substitutions
    if f.command == "run":
        out["phases"] = {
            k: {"planned": r.planned, "flown": r.flown, "complete": r.complete} for k, r in f.results.items()
        }
    if f.error is not None:
        out["error"] = f.error
    return out


def _tasks_done(f: RunFacts, op: PhaseResult | None, reached: list[str], complete: bool) -> list[str]:
    """Tasks whose work is done: an operation's, as its rovers reported them; a complete ``run``'s
    reached tasks (the dwell was their work); none for ``deploy`` or ``collect`` alone."""
    if op is not None:
        return list(op.tasks_done)
    return list(reached) if f.command == "run" and complete else []


def _makespans(
    f: RunFacts, dep: PhaseResult | None, col: PhaseResult | None, complete: bool
) -> tuple[float | None, float | None]:
    if dep is not None and dep is col:  # an operation
        return dep.planned, dep.flown if complete else None
    if f.command == "deploy":
        return (dep.planned, dep.flown) if dep else (None, None)
    if f.command == "collect":
        return (col.planned, col.flown) if col else (None, None)
    # run: deploy + dwell + collect (planning and uploads between the phases not counted)
    dwell = f.dwell_planned if f.dwell_planned is not None else f.mission.dwell
    planned = (
        dep.planned + dwell + col.planned
        if dep and col and dep.planned is not None and col.planned is not None
        else None
    )
    flown = (
        dep.flown + (f.dwell_flown or 0.0) + col.flown
        if complete and dep and col and dep.flown is not None and col.flown is not None
        else None
    )
    return planned, flown


def _accounting(
    f: RunFacts, dep: PhaseResult | None, col: PhaseResult | None, unserved: list[str], lost: list[str]
) -> dict[str, Any]:
    """Summary fields that account for every task and every rover: why a task was not reached,
    tasks added/removed while flying, and for each rover not loaded nor lost: on the deck (only
    when it is) or left in the field (``rovers_left``: position, state, task, battery, airborne,
    and why when the collection let it go or could not load it), and ``rovers_airborne``: those
    of them in the air. Airborne follows telemetry (landed state, else height), never the last
    command; null when the rover sent neither."""
    out: dict[str, Any] = {"last_replan": f.state.last_replan}
    if f.command != "collect":
        reasons = dep.unserved_reasons if dep else {}
        out["tasks_unserved_reasons"] = {
            t: reasons.get(t, "the deployment did not get to it") for t in unserved
        }
        out["tasks_added"] = dep.tasks_added if dep else []
        out["tasks_removed"] = dep.tasks_removed if dep else []
    loaded = set(col.rovers_loaded) if col else set()
    unreachable = set(col.rovers_unreachable) if col else set()
    launched = set(dep.launched) if dep else set()
    why = {**(col.rovers_failed if col else {}), **(col.rovers_let_go if col else {})}
    on_deck: list[str] = []
    airborne: dict[str, Any] = {}
    left: dict[str, Any] = {}
    last: dict[str, Any] = {}
    for v in f.state.rovers():
        pos = [round(c, 2) for c in v.enu] if v.enu is not None else None
        if v.id in loaded:
            continue
        up = _is_airborne(v)
        if v.id in lost:
            last[v.id] = pos
        elif not up and v.id not in launched | unreachable | set(why) and _on_the_deck(f, v):
            on_deck.append(v.id)
        else:
            left[v.id] = {"position": pos, "state": v.state, "task": v.task, "battery_pct": v.battery_pct,
                          "airborne": up}
            if v.id in why:
                left[v.id]["why"] = why[v.id]
            if up:
                airborne[v.id] = {"position": pos, "state": v.state, "task": v.task,
                                  "battery_pct": v.battery_pct}
    out["rovers_on_deck"] = on_deck
    out["rovers_airborne"] = airborne
    out["rovers_left"] = left
    out["rovers_lost_last_position"] = last
    return out


def _lost_reason(rid: str, missing: dict[str, str], state: FleetState) -> str:
    if rid in missing:
        return f"did not answer at connect: {missing[rid]}"
    return "link lost while flying the mission" if state.vehicles[rid].connected else "link lost"


def _is_airborne(v: VehicleState) -> bool | None:
    """By telemetry: the landed state when the rover reports one, else its height above home;
    None (unknown) without either. A rover whose flight was reported (climbing, en route, on its
    task: MISSION_ITEM_REACHED and the like) after its last position or landed state is in the air:
    that report is the newer telemetry."""
    if v.on_ground is not None:
        up: bool | None = not v.on_ground
    elif v.alt is not None:
        up = v.alt > AIRBORNE_HEIGHT
    else:
        up = None
    newer = v.state_at is not None and (v.telemetry_at is None or v.state_at > v.telemetry_at)
    if not up and newer and v.state in _IN_THE_AIR:
        return True
    return up


_IN_THE_AIR = frozenset({VehicleStatus.CLIMBING, VehicleStatus.EN_ROUTE, VehicleStatus.ON_TASK})


def _on_the_deck(f: RunFacts, v: VehicleState) -> bool:
    if f.command == "collect":
        return v.state in (VehicleStatus.ON_DECK, VehicleStatus.REFUSED, VehicleStatus.UNKNOWN)
    return v.state in (VehicleStatus.ON_DECK, VehicleStatus.REFUSED)


__all__ = ["SUMMARY_SCHEMA", "RunFacts", "build_summary"]
