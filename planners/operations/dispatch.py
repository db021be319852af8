"""The operation planner's construction: the carrier serves the sites in order, stop after stop.

At its current site the carrier makes the next stop the earlier of two events: rovers on the deck
ready for a launch (with tasks of the site left), or the first returning rover (with the others
back within one landing and loading, picked up together). A pick-up stop also launches the rovers
ready by its end, and those it picks up that keep their battery. A rover whose battery would not
last until the stop after this one is picked up first (its deadline). When the site's tasks are
all launched the carrier moves on; a rover still out that could not reach the next site is picked
up before it leaves. At the end the carrier picks up everyone at its last site, or (``chase``)
drives to them."""

from __future__ import annotations

import math
import random
from dataclasses import dataclass

from planners.core.problem import PlanningError, Vec3
from planners.operations.chains import assign
from planners.operations.live import LiveState, seed
from planners.operations.plan import OperationPlan
from planners.operations.problem import OperationProblem, OpTask
from planners.operations.schedule import Chain, Schedule
from planners.operations.sites import Site


@dataclass(frozen=True)
class Policy:
    radius: float  # m: a site's tasks fit a circle this wide
    cap: float  # s of work per sortie at most (inf: the battery decides)
    margin: float  # s of battery kept for waiting to be picked up
    swap_below: float = 1.0  # swap a rover picked up with less than this fraction of its air time left
    chase: bool = False  # at the end, drive to the rovers (below their last task), not call them back
    jitter: int = 0  # a seed: a task's duration counts up to 30 % more or less in the launch order (0: none)


def dispatch(problem: OperationProblem, sites: list[Site], policy: Policy, name: str,
             start: LiveState | None = None) -> OperationPlan:
    """The schedule of the whole operation, or of its rest from ``start`` (PlanningError when a
    rover's battery cannot be kept)."""
    sch = Schedule(problem, policy.swap_below)
    if start is not None:
        seed(sch, start)
        if sites:  # rovers in the air that could not wait for the carrier at the first site: here first
            _before_leaving(sch, sch.pos, sites[0].point, policy)
    rng = random.Random(policy.jitter)
    weight = {t.id: 1.0 + (0.3 * rng.uniform(-1.0, 1.0) if policy.jitter else 0.0) for t in problem.tasks}
    for n, site in enumerate(sites):
        left = sorted((problem.tasks[i] for i in site.tasks), key=lambda t: (-t.duration * weight[t.id],
                                                                             t.id))
        while left:
            _step(sch, site.point, left, policy)
        if n + 1 < len(sites):
            _before_leaving(sch, site.point, sites[n + 1].point, policy)
    while sch.air:
        if policy.chase:
            _chase(sch)
        else:
            _step(sch, sch.pos, [], policy)
    return sch.finish(name)


def _window(problem: OperationProblem) -> float:
    """Rovers back within this long of the first one share its pick-up stop (saves a landing and loading)."""
    return problem.carrier.collect_stop_time


def _step(sch: Schedule, point: Vec3, left: list[OpTask], policy: Policy) -> None:
    """One stop at ``point``: a launch, or a pick-up (with launches), or an urgent pick-up."""
    p = sch.p
    arrive = sch.free + sch.drive(point)
    deck = sorted(sch.ready, key=lambda r: (sch.ready[r], r))
    meets = {r: sch.earliest_meet(r, point) for r in sch.air}
    t_launch = max(arrive, sch.ready[deck[0]]) if deck and left else math.inf
    t_pick = min(meets.values(), default=math.inf)
    pickups: list[str] = []
    after: dict[str, float] = {}  # picked-up rovers flying on at once: air s of their battery flown
    if t_launch <= t_pick:
        launchers, not_before, loaded = [r for r in deck if sch.ready[r] <= t_launch], t_launch, t_launch
    else:
        pickups = sorted(r for r in meets if meets[r] <= t_pick + _window(p))
        land = max(arrive, *(meets[r] for r in pickups))
        loaded = land + p.carrier.collect_stop_time
        after = _kept_batteries(sch, point, pickups, land)
        ready = [r for r in deck if sch.ready[r] <= loaded] + sorted(after)
        launchers, not_before = (ready if left else []), 0.0

    def battery(r: str) -> float:
        return p.air_budget - after[r] if r in after else sch.battery(r)

    launches, flat = assign(point, launchers, left, p, policy.margin, policy.cap, battery)
    flat = [r for r in flat if r not in after]
    if flat:  # on the deck with too little battery for any task left: a swap first
        _swap(sch, flat)
        if not launches and not pickups:
            return
    depart = loaded + (p.carrier.deploy_stop_time if launches else 0.0)
    urgent = [r for r in sch.air if r not in pickups and sch.deadline(r, point) < depart]
    if urgent:
        _urgent_pickup(sch, point, urgent)
        return
    sch.add_stop(point, pickups, launches, not_before)
    _consume(left, launches)


def _kept_batteries(sch: Schedule, point: Vec3, pickups: list[str], land: float) -> dict[str, float]:
    """The rovers of a pick-up that keep their battery (no swap: enough of it left), with the air
    seconds of it they will have flown: a stop may launch them again at once."""
    p = sch.p
    used = {r: sch.air[r].used_before + sch.air_if_landing(r, point, land) for r in pickups}
    return {r: u for r, u in used.items() if p.air_budget - u >= sch.swap_below * p.air_budget}


def _swap(sch: Schedule, rovers: list[str]) -> None:
    for r in rovers:
        if sch.used[r] == 0.0:
            raise PlanningError(f"no task left fits rover {r}'s full battery with the flights to it and back")
        sch.swap(r)


def _consume(left: list[OpTask], launches: list[tuple[str, Chain]]) -> None:
    taken = {t.id for _, chain in launches for t in chain.tasks}
    left[:] = [t for t in left if t.id not in taken]


def _urgent_pickup(sch: Schedule, point: Vec3, urgent: list[str]) -> None:
    """Pick up the rover with the earliest deadline now (and those back by then)."""
    first = min(urgent, key=lambda r: sch.deadline(r, point))
    start = max(sch.free + sch.drive(point), sch.earliest_meet(first, point))
    if start > sch.deadline(first, point):
        raise PlanningError(f"rover {first}'s battery does not last until the carrier can pick it up")
    pickups = sorted(r for r in sch.air if sch.earliest_meet(r, point) <= start)
    sch.add_stop(point, pickups, [])


def _below(sch: Schedule, rover: str) -> Vec3:
    last = sch.air[rover].last
    return (last[0], last[1], 0.0)


def _meet_below(sch: Schedule, rover: str) -> float:
    """When the carrier, driving there now, and the rover can meet below the rover's last task."""
    q = _below(sch, rover)
    return max(sch.free + sch.drive(q), sch.earliest_meet(rover, q))


def _chase(sch: Schedule) -> None:
    """One pick-up stop of the end: below the rover the carrier can meet first, unless another
    rover's battery would not last until the carrier reached it afterwards (then that one first)."""
    order = sorted(sch.air, key=lambda r: (_meet_below(sch, r), r))
    slack = {r: sch.deadline(r, _below(sch, r)) - _meet_below(sch, r) for r in order}
    after = sch.p.carrier.collect_stop_time + max((sch.drive(_below(sch, r)) for r in order), default=0.0)
    first = order[0]
    late = [r for r in order[1:] if slack[r] < _meet_below(sch, first) - sch.free + after]
    if late:
        first = min(late, key=lambda r: slack[r])
    if slack[first] < 0.0:
        raise PlanningError(f"rover {first}'s battery does not last until the carrier can pick it up")
    q, start = _below(sch, first), _meet_below(sch, first)
    window = sch.p.carrier.collect_stop_time
    pickups = sorted(r for r in sch.air if sch.earliest_meet(r, q) <= start + window
                     and sch.deadline(r, q) >= start + window)
    sch.add_stop(q, pickups if first in pickups else [first], [])


def _before_leaving(sch: Schedule, here: Vec3, there: Vec3, policy: Policy) -> None:
    """Pick up here the rovers that could not wait for the carrier at the next site."""
    at_next = sch.free + sch.drive(there) + policy.margin
    must = [r for r in sch.air if sch.deadline(r, there) < max(at_next, sch.earliest_meet(r, there))]
    while must:
        _urgent_pickup(sch, here, must)
        must = [r for r in must if r in sch.air]
