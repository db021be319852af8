"""Open-space deployment (dissertation ch. 4): the two-cluster optimum and the path generator.

Vocabulary follows the chapter: tasks are grouped into clusters P_ω; the carrier stops once
per cluster at a deployment point q_ω, unloads, and the cluster's rovers fly to their tasks.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence

from planners.core.clustering import Divider, divide_cluster
from planners.core.driver import search
from planners.core.moves import Move, merge, relocate_nearest
from planners.core.plan import Plan
from planners.core.problem import DeployProblem, PlanningError, Point2, refuse_obstacles
from planners.core.search import merge_neighbours, reorder, split_loop, swap_neighbours
from planners.core.trace import Trace, untraced
from planners.deploy.build import build_plan
from planners.deploy.cluster import DeployInstance
from planners.deploy.path import PathBuilder, Route
from planners.deploy.polish import place_finely, smooth
from planners.deploy.two_task import plan_two_tasks


class DeploySpace:
    """Deployment's side of the search driver (``planners.core.driver.SearchSpace``): the quick
    placement of ch. 4.4 (``PathBuilder.route``), the final placement (``planners.deploy.polish``),
    the smoothed stops, plans built by ``build_plan`` and the quick descent's moves (tasks handed
    to the neighbouring cluster, ``QD_KEEP`` nearest it, and merges)."""

    def __init__(self, problem: DeployProblem, builder: PathBuilder) -> None:
        self.problem, self.builder = problem, builder
        self.inst = inst = builder.inst
        self.size = len(inst.pts)
        self.fits = inst.fits_quick
        self.rebuild = builder.route
        keep = next(k for upto, k in QD_KEEP if self.size <= upto)
        # (the moves hold the instance, not this space: no reference cycle, so that a plan's caches
        # are freed when it returns, not by the garbage collector in a later plan's time)
        self.cheap: Sequence[Move] = (relocate_nearest(nearness(inst), keep), merge)

    def finish(self, route: Route, small: bool, improve: bool) -> Route:
        return place_finely(self.builder, route, small, improve)

    def smooth(self, route: Route) -> Route:
        return smooth(self.builder, route)

    def flown(self, route: Route) -> float:
        return build_plan(self.problem, "lee", route.clusters, route.positions).makespan

    def ranking(self) -> None:
        return None


def nearness(inst: DeployInstance) -> Callable[[Sequence[int]], Callable[[int], float]]:
    """``near(cluster)``: the key ranking tasks by their squared distance to ``cluster``'s centre
    (the quick descent's ``relocate_nearest``)."""
    pts = inst.pts

    def near(cluster: Sequence[int]) -> Callable[[int], float]:
        c = inst.geometry(cluster).center
        return lambda task: (pts[task][0] - c[0]) ** 2 + (pts[task][1] - c[1]) ** 2
    return near


def lee_clusters(problem: DeployProblem, improve: bool = True, t0: float | None = None,
                 tiny_search: bool = True, trace: Trace = untraced,
                 ) -> tuple[list[list[int]], list[Point2], float]:
    """Algorithm 4.1–4.2: divide until every cluster fits d_deploy, then the split/swap/merge loop
    that keeps the fastest path; with ``improve``, then re-sequence, swap and merge clusters while
    that helps (dividing again after them gained nothing on 240 instances of n = 3–1000: left out),
    then the search driver (``planners.core.driver.search``: moves, final placement, the searches
    of tiny problems, a budget's anytime search). Returns clusters in visiting order, stops and
    makespan. ``tiny_search`` False leaves out the searches of tiny problems: a quick plan for
    screening many (``plan_lee_screen``). ``trace`` is called with each phase's name and the
    makespan after it (``bench/phases.py``)."""
    inst = DeployInstance(problem)
    builder = PathBuilder(inst)
    if not inst.pts:
        return [], [], 0.0
    route = _divided(builder, improve, trace)
    best = search(DeploySpace(problem, builder), route, improve=improve, budget_ms=problem.budget_ms, t0=t0,
                  seed=problem.seed, tiny_search=tiny_search, trace=trace)
    return best.clusters, best.positions, best.makespan


def _divided(builder: PathBuilder, improve: bool, trace: Trace) -> Route:
    """Algorithm 4.1 (divide until every cluster fits d_deploy) and 4.2 (the split/swap/merge loop),
    then with ``improve`` up to two rounds of re-sequencing, swapping and merging while they help."""
    inst, start, n = builder.inst, builder.start, len(builder.inst.pts)
    # Initial clustering (Algorithm 4.1): divide until every cluster fits d_deploy.
    clusters: list[list[int]] = [list(range(n))]
    idx = 0
    while idx < len(clusters):
        if not inst.fits(clusters[idx]):
            prev = start if idx == 0 else inst.geometry(clusters[idx - 1]).center
            near, far = divide_cluster(clusters[idx], inst.pts, (*prev, 0.0))
            clusters[idx: idx + 1] = [near, far]
        else:
            idx += 1
    divider = Divider(inst.pts)  # the split loop divides the same clusters again after a change

    def divide(route: Route, idx: int) -> tuple[list[int], list[int]]:
        prev = start if idx == 0 else route.positions[idx - 1]
        return divider(route.clusters[idx], (*prev, 0.0))

    tried: set = set()
    route = split_loop(builder.route(clusters), divide, tried)  # Algorithm 4.2
    trace("dissertation", route.makespan)
    for _ in range(2 if improve else 0):  # improvement search beyond the dissertation
        better = reorder(route, [g.center for g in route.geos], start, builder.route)
        trace("reorder", min(better.makespan, route.makespan))
        better = merge_neighbours(swap_neighbours(better), inst.fits_quick)
        trace("swap and merge", min(better.makespan, route.makespan))
        if better.makespan >= route.makespan - 1e-9:
            break
        route = better
    return route


# (up to n tasks, k): the tasks of a cluster nearest its neighbour that the quick descent offers to it
# (big clusters of big problems: each offer costs an enclosing circle)
QD_KEEP = ((60, 3), (300, 1), (math.inf, 0))


def plan_lee(problem: DeployProblem, tiny_search: bool = True) -> Plan:
    """The dissertation's deployment path generator (ch. 4.4), planner name ``lee``."""
    t0 = time.perf_counter()
    refuse_obstacles(problem, "lee")
    if len(problem.rover_ids()) < len(problem.tasks):
        raise PlanningError(f"{len(problem.tasks)} tasks need as many rovers, only "
                            f"{len(problem.rover_ids())} on the carrier")
    clusters, positions, _ = lee_clusters(problem, t0=t0, tiny_search=tiny_search)
    plan = build_plan(problem, "lee", clusters, positions)
    if len(problem.tasks) == 2:  # where it applies, the two-task optimum of ch. 4.3 (jointly placed stops)
        two = plan_two_tasks(problem)
        if two.makespan < plan.makespan:
            index = {t.id: i for i, t in enumerate(problem.tasks)}
            two_clusters: list[list[int]] = []
            for s in two.stops:
                tasks = [leg.task for leg in s.rovers]
                if None in tasks:
                    raise PlanningError("the two-task plan has a rover leg without a task")
                two_clusters.append([index[t] for t in tasks if t is not None])
            plan = build_plan(problem, "lee", two_clusters,
                              [(s.position[0], s.position[1]) for s in two.stops])
    plan.compute_ms = (time.perf_counter() - t0) * 1e3
    return plan


def plan_lee_screen(problem: DeployProblem) -> Plan:
    """``lee`` without the searches of tiny problems: tens of times cheaper on a few tasks, within a
    few per cent; the teams allocation screens its candidate shares with it
    (``planners.SCREEN_PLANNERS``)."""
    return plan_lee(problem, tiny_search=False)
