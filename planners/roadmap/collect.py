"""Collection among obstacles on the roadmap (planner ``lee-graph`` for ``--collect``).

The dissertation leaves collection among obstacles open; this is chapter 6's machinery applied
to chapter 5's problem:

* the roadmap of ch. 6 (global PRM with the carrier start and the rovers as nodes, local PRM in a
  cluster's region, shortest paths, shortcutting);
* clusters as in Algorithm 6.3: the rover nearest the carrier along the roadmap (eq. 6.8) and the
  rovers whose reach discs can meet its disc (distance < ρ_near + ρ_j, the collection form of
  the 2·d_deploy rule), divided by Algorithm 6.1 while no node is reachable by all of them;
* meeting nodes: roadmap nodes from which every rover of the cluster is within its range along
  the roadmap (rover i at height z flies a ground path L descending evenly: √(L² + z²) ≤ range);
* the waiting carrier of ch. 5 (eq. 5.2): eta_k = max(eta_{k-1} + leg_k, latest rover arrival)
  + load_time. The meeting node minimises that eta plus the carrier's roadmap time on to the
  next cluster's nearest rover (the time form of eq. 6.10); the last one minimises eta.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np

from planners.core.geometry import enclosing_ball
from planners.core.plan import Plan, RoverLeg, Stop
from planners.core.problem import CollectProblem, PlanningError
from planners.core.timing import RANGE_MARGIN, carrier_leg, leg_time, retime
from planners.roadmap.costs import RoadmapCosts
from planners.roadmap.search import search_greedy
from planners.roadmap.world import GraphWorld, ground_path, node_xy


class _Collect:
    def __init__(self, p: CollectProblem, local: bool) -> None:
        self.p = p
        pos = np.array([r.position for r in p.rovers], dtype=float).reshape(-1, 3)
        rng = np.array([r.range for r in p.rovers], dtype=float)
        for r in p.rovers:
            if r.range < r.position[2]:
                raise PlanningError(f"rover {r.id} is {r.position[2]:g} m up with only {r.range:g} m of "
                                    "range: it cannot reach the ground")
        rho = np.sqrt(np.maximum(np.maximum(rng - RANGE_MARGIN, 0.0) ** 2 - pos[:, 2] ** 2, 0.0))
        if p.bounds is not None:
            (x0, y0), (x1, y1) = p.bounds
            spread = (x1 - x0 + y1 - y0) / 2 * p.roadmap.phi
        else:
            spread = 0.0
        # edges as long as the shortest reach (but at least eq. 6.6's map term, at most the longest reach)
        d_edge = float(min(max(spread, float(rho.min()), 1.0), max(float(rho.max()), 1.0)))
        self.w = GraphWorld(p.obstacles, p.bounds, p.start, pos, [r.id for r in p.rovers], "rover", rho,
                            d_edge, p.roadmap, p.seed, local)
        self.z = pos[:, 2]
        self.prev = 0
        self.eta = 0.0
        self.heading = p.heading
        self.stops: list[tuple[int, list[int]]] = []

    def arrivals(self, mem: Sequence[int], node: int) -> float:
        dist = self.w.rm.distances([self.w.node(i) for i in mem])
        return max(leg_time(math.hypot(dist[k, node], self.z[i]), self.p.rover) for k, i in enumerate(mem))

    def run(self) -> list[tuple[int, list[int]]]:
        w, cr = self.w, self.p.carrier
        tx = w.targets
        remaining = list(range(len(tx)))
        while remaining:
            d_prev = w.rm.shortest(self.prev)[0]
            nearest = min(remaining, key=lambda i: (d_prev[w.node(i)], i))  # eq. 6.8
            mem = [nearest] + [i for i in remaining if i != nearest
                               and math.dist(tx[i, :2], tx[nearest, :2]) < w.rho[i] + w.rho[nearest]]
            nxt = self._next(mem, [i for i in remaining if i not in mem])
            while True:
                cands, _ = w.candidates(mem, node_xy(w.rm, self.prev), None if nxt is None else
                                        (float(tx[nxt, 0]), float(tx[nxt, 1])))
                if len(cands):
                    break
                mem = w.divide(mem, nearest)  # Algorithm 6.1
            rest = [i for i in remaining if i not in mem]
            nxt = self._next(mem, rest)
            # every local PRM is done: score the candidates on the final graph (eq. 5.2 + 6.10)
            dist = w.rm.distances([w.node(i) for i in mem])
            d_prev = w.rm.shortest(self.prev)[0]
            rover_t = np.max([[leg_time(math.hypot(dist[k, c], self.z[i]), self.p.rover) for c in cands]
                              for k, i in enumerate(mem)], axis=0)
            carrier_t = np.array([leg_time(d_prev[c], cr.motion) for c in cands])
            score = np.maximum(self.eta + carrier_t, rover_t) + cr.collect_stop_time
            if nxt is not None:
                d_next = w.rm.shortest(w.node(nxt))[0]
                score = score + np.array([leg_time(d_next[c], cr.motion) for c in cands])
            node = int(cands[int(np.argmin(score))])
            path = ground_path(w.rm.smoothed_path(self.prev, node))
            dt, self.heading = carrier_leg(path, self.heading, cr)
            self.eta = max(self.eta + dt, self.arrivals(mem, node)) + cr.collect_stop_time
            self.stops.append((node, mem))
            self.prev = node
            remaining = rest
        return self.stops

    def _next(self, mem: Sequence[int], rest: Sequence[int]) -> int | None:
        if not rest:
            return None
        tx = self.w.targets
        lam = enclosing_ball([tuple(tx[i, :2]) for i in mem]).center  # eq. 6.9
        return min(rest, key=lambda i: (math.dist(tx[i, :2], lam), i))


def plan_collect_lee_graph(problem: CollectProblem, local_prm: bool = True, search: bool = True) -> Plan:
    """Collection on a probabilistic roadmap with the waiting carrier of ch. 5; ``lee-graph``. With
    ``search``, then the moves of the open-space planners on the roadmap
    (``planners.roadmap.search``), kept when they make the plan faster."""
    t0 = time.perf_counter()
    if not problem.rovers:
        return Plan(kind="collect", planner="lee-graph", start=problem.start, heading=problem.heading,
                    stops=[])
    col = _Collect(problem, local_prm)
    order = col.run()
    costs = RoadmapCosts(col.w, problem.carrier, problem.rover, toward=False)
    plan = build_collect_graph_plan(problem, col.w, order, costs)
    if search:
        plan = search_greedy(order, costs, problem.heading, False,
                             lambda o: build_collect_graph_plan(problem, col.w, o, costs), plan,
                             problem.budget_ms, problem.seed, t0)
    plan.compute_ms = (time.perf_counter() - t0) * 1e3
    return plan


def build_collect_graph_plan(problem: CollectProblem, w: GraphWorld,
                             order: Sequence[tuple[int, Sequence[int]]],
                             costs: RoadmapCosts | None = None) -> Plan:
    """Carrier sub-routes and rover routes on the final roadmap, shortcut, and timed (eq. 5.2); the
    paths the search timed (``costs``) when given."""
    rm = w.rm
    costs = costs or RoadmapCosts(w, problem.carrier, problem.rover, toward=False)
    stops: list[Stop] = []
    prev = 0
    for node, mem in order:
        here = node_xy(rm, node)
        carrier_path = list(costs.path(prev, node))
        if prev == 0:
            carrier_path[0] = problem.start
        legs = []
        for i in mem:
            r = problem.rovers[i]
            ground = costs.rover_path(i, node)
            path = w.climb_path(ground, r.position[2], 0.0)
            path[0] = r.position
            if math.hypot(sum(math.dist(a, b) for a, b in zip(ground, ground[1:], strict=False)),
                          r.position[2]) > r.range:
                raise PlanningError(f"rover {r.id}: route to its meeting node longer than its range")
            legs.append(RoverLeg(rover=r.id, path=path))
        stops.append(Stop(position=(here[0], here[1], 0.0), carrier_path=carrier_path, rovers=legs))
        prev = node
    plan = Plan(kind="collect", planner="lee-graph", start=problem.start, heading=problem.heading,
                stops=stops)
    plan.roadmap = rm
    return retime(plan, problem.carrier, problem.rover)


def plan_collect_lee_graph_screen(problem: CollectProblem) -> Plan:
    """Algorithm 6.3 alone (no search): the teams allocation screens its candidate shares with it
    (``planners.SCREEN_PLANNERS``)."""
    return plan_collect_lee_graph(problem, search=False)
