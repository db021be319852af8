"""The live state of a flying operation as the planner takes it (:class:`planners.operations.LiveState`):
the carrier where it stands, the rovers on the deck with what their batteries have left (a rover
whose swap is queued counts as full), the rovers in the air with their work left, where they are
and the battery they have flown; and the problem of the work no rover has."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable

from fleetctl.run.context import RunContext
from fleetctl.run.launch import rover_on_deck
from fleetctl.run.operation.board import OperationBoard
from fleetctl.run.operation.sortie import SortieFlight
from planners.operations import InFlight, LiveState, OperationProblem, OpTask

Vec3 = tuple[float, float, float]


def flown(ctx: RunContext, rover: str, endurance: float) -> float:
    """Air seconds of its battery a rover has used, from its battery reading (0: unknown, full)."""
    frac = ctx.fleet.rovers[rover].battery_fraction
    return 0.0 if frac is None else max(0.0, (1.0 - frac) * endurance)


def in_flight(ctx: RunContext, f: SortieFlight, tasks: dict[str, OpTask], endurance: float) -> InFlight:
    v = f.vehicle
    pos = v.enu or f.pickup.position
    work = f.work_left()
    left = tuple(dataclasses.replace(tasks[t], duration=max(w, 0.0)) for t, w in work)
    first = max(tasks[work[0][0]].duration - work[0][1], 0.0) if work else 0.0  # its work so far
    return InFlight(v.name, (pos[0], pos[1], max(pos[2], 0.0)), left, flown(ctx, v.name, endurance),
                    v.on_ground is True, first)


def live_problem(ctx: RunContext, board: OperationBoard, tasks: dict[str, OpTask],
                 flights: Iterable[SortieFlight], swapping: set[str],
                 carrier: tuple[Vec3, float]) -> tuple[OperationProblem, LiveState]:
    """The rest of the operation from now (see the module docstring); ``tasks``: every task of the
    operation now (with changes)."""
    base = ctx.mission.operation_problem()
    air = [in_flight(ctx, f, tasks, base.endurance) for f in flights if not f.vehicle.lost]
    up = {f.rover for f in air}
    taken = {t.id for f in air for t in f.tasks}
    left = tuple(tasks[t] for t in board.left() if t not in taken)
    deck = {r: 0.0 if r in swapping else flown(ctx, r, base.endurance) for r in base.rovers
            if r not in up and r not in board.lost and rover_on_deck(ctx, ctx.fleet.rovers[r])}
    pos, heading = carrier
    problem = dataclasses.replace(base, start=pos, heading=heading, tasks=left, rovers=(*deck, *up))
    return problem, LiveState(pos, heading, deck, tuple(air))


__all__ = ["flown", "in_flight", "live_problem"]
