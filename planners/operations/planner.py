"""The operation planner (``plan_operation``): the dispatch construction
(:mod:`planners.operations.dispatch`) under a few policies (site radius, work per sortie, when to
swap a battery), then
on perturbed task tours (a random segment of the tour reversed) and launch orders (durations
jittered), seeded by ``problem.seed``, for a fixed number of rounds; the earliest end is kept."""

from __future__ import annotations

import math
import random
import time
from dataclasses import replace

from planners.core.problem import PlanningError
from planners.operations.dispatch import Policy, dispatch
from planners.operations.live import LiveState, call_back, recovery
from planners.operations.plan import OperationPlan
from planners.operations.problem import OperationProblem
from planners.operations.sites import cut_sites, task_tour

RADII = (1.0, 0.6, 0.3)  # site radius as a fraction of the deploy range
CAPS = (math.inf, 0.5, 0.3)  # work per sortie as a fraction of the battery's air time (inf: no cap)
SWAP_BELOW = (1.0, 0.5)  # swap a returning rover's battery when less than this fraction of it is left
CHASE = (False, True)  # at the end, call the rovers back to the carrier, or drive to them
ROUNDS = 120  # perturbed tours and launch orders tried after the policies
TIME_LIMIT = 1.5  # s of wall time at most for the rounds (a guard; the rounds end first on usual sizes)


def policies(problem: OperationProblem) -> list[Policy]:
    c = problem.carrier
    margin = 2.0 * (c.deploy_stop_time + c.collect_stop_time)
    return [Policy(problem.deploy_range * r, problem.air_budget * cap if math.isfinite(cap) else math.inf,
                   margin, below, chase)
            for r in RADII for cap in CAPS for below in SWAP_BELOW for chase in CHASE]


def _try(problem: OperationProblem, tour: list[int], policy: Policy,
         start: LiveState | None = None) -> OperationPlan | None:
    try:
        return dispatch(problem, cut_sites(problem, tour, policy.radius), policy, "operation", start)
    except PlanningError:
        return None


def _perturbed(tour: list[int], rng: random.Random) -> list[int]:
    """The tour with one random segment reversed."""
    if len(tour) < 3:
        return list(tour)
    i, j = sorted(rng.sample(range(len(tour) + 1), 2))
    return tour[:i] + tour[i:j][::-1] + tour[j:]


def plan_operation(problem: OperationProblem, start: LiveState | None = None,
                   rounds: int = ROUNDS) -> OperationPlan:
    """Schedule the whole operation, or (``start``) its rest from a live state: ``problem.tasks``
    the work no rover has, ``problem.rovers`` every rover of the state; ``rounds`` perturbed
    tours after the policies (PlanningError when no schedule keeps every battery). From a live
    state where a rover in the air is short of battery for its work left, the rest is also planned
    with that rover called back early (:func:`~planners.operations.live.call_back`: keeping the
    tasks that fit, and keeping none); the earliest end is kept. When none keeps every battery
    above its reserve, a live state's rovers in the air are brought back by a recovery plan
    (``recovery``: no launches, the reserve given up, the rovers short of battery called back)."""
    t0 = time.perf_counter()
    if not problem.rovers:
        raise PlanningError("an operation needs at least one rover")
    variants: list[tuple[OperationProblem, LiveState | None, dict[str, list[str]]]] = [(problem, start, {})]
    for keep in (True, False) if start is not None else ():
        cb = call_back(problem, start, keep) if start is not None else None
        if cb is not None and all(cb.called_back != v[2] for v in variants):
            variants.append((replace(problem, tasks=problem.tasks + cb.dropped), cb.state, cb.called_back))
    best: OperationPlan | None = None
    error = PlanningError("no schedule")
    for p, state, called in variants:
        try:
            plan = _search(p, state, rounds, t0)
        except PlanningError as exc:
            error = exc
            continue
        plan.called_back = called
        if best is None or plan.makespan < best.makespan:
            best = plan
    if best is None and start is not None and start.in_flight:
        best = _recover(problem, start, rounds, t0, error)
    if best is None:
        raise error
    best.compute_ms = (time.perf_counter() - t0) * 1e3
    return best


def _recover(problem: OperationProblem, start: LiveState, rounds: int, t0: float,
             error: PlanningError) -> OperationPlan:
    """The recovery plan (:func:`~planners.operations.live.recovery`): the rovers in the air back."""
    p, state, called = recovery(problem, start)
    try:
        plan = _search(p, state, rounds, t0)
    except PlanningError:
        raise error from None
    plan.called_back, plan.recovery = called, True
    plan.notes.append("recovery: no plan keeps every battery above its reserve; the rovers in the air "
                      "come back, the work left is planned once they are aboard")
    return plan


def _search(problem: OperationProblem, start: LiveState | None, rounds: int, t0: float) -> OperationPlan:
    """The policies, then ``rounds`` perturbed tours and launch orders: the earliest end."""
    tour = task_tour(problem) if problem.tasks else []
    found = [(p, pol, tour) for pol in policies(problem)
             if (p := _try(problem, tour, pol, start)) is not None]
    if not found:
        raise PlanningError("no schedule keeps every rover's battery (a task too long or too far to "
                            "fly to, work and fly back from on one battery)")
    best, policy, best_tour = min(found, key=lambda f: f[0].makespan)
    rng = random.Random(problem.seed)
    for _ in range(rounds):
        if time.perf_counter() - t0 > TIME_LIMIT:
            break
        trial_tour = _perturbed(best_tour, rng)
        trial_policy = replace(rng.choice([policy, *(f[1] for f in found)]), jitter=rng.randrange(1, 2**31))
        plan = _try(problem, trial_tour, trial_policy, start)
        if plan is not None and plan.makespan < best.makespan:
            best, policy, best_tour = plan, trial_policy, trial_tour
    return best
