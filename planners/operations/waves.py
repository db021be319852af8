"""The waves baseline: what an operator does with today's fleetctl, one ``run`` after another.

Each wave takes as many tasks as there are rovers (the ones nearest the carrier), deploys them
with the deployment planner ``lee`` (``planners.DEPLOY_PLANNERS``), waits until every task of the
wave has had its work, collects every rover with the collection planner ``lee``
(``planners.COLLECT_PLANNERS``; the rovers leave their tasks when the collection starts), and the
next wave's rovers leave the deck once their battery is swapped (the carrier drives meanwhile). A
wave whose rovers' batteries would not last is made smaller (its longest task waits for a later
wave). Times are the operation's (:mod:`planners.operations.schedule`): the same time model.
"""

from __future__ import annotations

import copy
import math
import time

from planners import COLLECT_PLANNERS, DEPLOY_PLANNERS
from planners.core.problem import CollectProblem, CollectRover, DeployProblem, Motion, PlanningError, Task
from planners.operations.plan import OperationPlan
from planners.operations.problem import OperationProblem, OpTask
from planners.operations.schedule import EPS, Schedule, chain_profile


def plan_waves(problem: OperationProblem) -> OperationPlan:
    t0 = time.perf_counter()
    sch = Schedule(problem)
    left = list(problem.tasks)
    while left:
        wave = _nearest(sch, left, len(problem.rovers))
        sch = _fly_wave_or_smaller(sch, wave)
        done = {v.task for s in sch.sorties for v in s.visits}
        left = [t for t in left if t.id not in done]
    plan = sch.finish("waves")
    plan.compute_ms = (time.perf_counter() - t0) * 1e3
    return plan


def _nearest(sch: Schedule, left: list[OpTask], n: int) -> list[OpTask]:
    return sorted(left, key=lambda t: (math.dist(t.position[:2], sch.pos[:2]), t.id))[:n]


def _fly_wave_or_smaller(sch: Schedule, wave: list[OpTask]) -> Schedule:
    """The schedule after one wave; without its longest task while the batteries do not last."""
    while True:
        trial = copy.deepcopy(sch)
        try:
            _wave(trial, wave)
            return trial
        except PlanningError:
            if len(wave) == 1:
                raise
            wave = sorted(wave, key=lambda t: (t.duration, t.id))[:-1]


def _wave(sch: Schedule, wave: list[OpTask]) -> None:
    p = sch.p
    deck = sorted(sch.ready, key=lambda r: (sch.ready[r], r))[: len(wave)]
    by_id = {t.id: t for t in wave}
    dp = DeployProblem(p.carrier, p.rover, p.deploy_range, sch.pos, sch.heading,
                       tuple(Task(t.id, t.position) for t in wave), rovers=tuple(deck),
                       takeoff_height=p.takeoff_height)
    for stop in DEPLOY_PLANNERS["lee"](dp).stops:
        launches = [(leg.rover, chain_profile(stop.position, [by_id[str(leg.task)]], p))
                    for leg in stop.rovers]
        sch.add_stop(stop.position, [], launches, not_before=max(sch.ready[r] for r, _ in launches))
    start = max(sch.air[r].end for r in sch.air)  # every task of the wave worked: the collection starts
    for a in sch.air.values():
        a.release = start
    cp = CollectProblem(p.carrier, _collect_motion(sch), sch.pos, sch.heading,
                        tuple(CollectRover(r, a.last, _range(sch, r, start))
                              for r, a in sorted(sch.air.items())),
                        approach_height=p.approach_height)
    stops = COLLECT_PLANNERS["lee"](cp).stops
    for k, stop in enumerate(stops):
        not_before = start + sch.drive(stop.position) if k == 0 else 0.0
        sch.add_stop(stop.position, [leg.rover for leg in stop.rovers], [], not_before=not_before)


def _collect_motion(sch: Schedule) -> Motion:
    """The collection's flights: from a ground task every rover is charged the take-off (the
    collection planners take one motion for all, as ``fleetctl`` does)."""
    ground = any(a.ground for a in sch.air.values())
    return Motion(sch.p.rover.max_speed, sch.p.rover.accel, sch.p.carrier.takeoff_time if ground else 0.0)


def _range(sch: Schedule, rover: str, start: float) -> float:
    """Metres of flight the rover's battery leaves for its way back when the collection starts."""
    a, p = sch.air[rover], sch.p
    used = a.air_to_end + (0.0 if a.ground else start - a.end) + p.carrier.land_time
    left = p.air_budget - EPS - used
    if left <= 0.0:
        raise PlanningError(f"rover {rover}'s battery does not last until the collection")
    return left * p.rover.max_speed
