"""A lower bound on the makespan of several teams that no allocation and no plan can beat."""

from __future__ import annotations

import math

import numpy as np

from planners.collect.lower_bound import collect_lower_bound
from planners.core.lower_bound import deploy_lower_bound, mst_length
from planners.core.problem import CollectProblem, DeployProblem
from planners.core.timing import leg_time
from planners.teams.clusters import ground_reach
from planners.teams.problem import TeamsProblem


def teams_lower_bound(problem: TeamsProblem) -> float:
    """The larger of two bounds (both ≤ the makespan of every allocation and every team plan):

    1. per item: whichever team serves item i, its plan serves at least item i, so the mission
       takes at least min over teams k of the one-team bound for item i alone
       (``deploy_lower_bound`` / ``collect_lower_bound``, which hold for any plan serving it);
       the maximum over items is a bound.
    2. stops (``_stops_bound``): the stops and the driving that K items needing a stop each force
       on the teams together.

    With one team, the one-team bound of the whole pool also holds.
    """
    if problem.n_items == 0:
        return 0.0
    bound = max(_item_bound(problem), _stops_bound(problem))
    if problem.n_teams == 1:
        bound = max(bound, _one_team_bound(problem.problems[0]))
    return bound


def _item_bound(problem: TeamsProblem) -> float:
    best = 0.0
    for i in range(problem.n_items):
        best = max(best, min(_one_team_bound(problem.restrict(k, [i])) for k in range(problem.n_teams)))
    return best


def _one_team_bound(p: DeployProblem | CollectProblem) -> float:
    return deploy_lower_bound(p) if isinstance(p, DeployProblem) else collect_lower_bound(p)


def _stops_bound(problem: TeamsProblem) -> float:
    """Argument. Items whose reach discs (centre the ground point, radius ρ = sqrt(range² − z²)) are
    pairwise disjoint — chosen greedily — need one stop each: K stops in all, K_k by team k, each
    costing at least h, the shortest stop time of the teams (``TeamsProblem.stop_time``). Some team
    makes ≥ ceil(K / m) of them, so the makespan is ≥ ceil(K / m) · h. Also, team k's route from its
    start through its stops is ≥ L_k long and takes ≥ g(L_k), g(L) = the least over the teams'
    carriers of leg_time(L) (``planners.core.lower_bound``: leg time is increasing, concave and zero at zero,
    so a split into legs never beats one leg; g, a minimum of such functions, is concave too, hence
    subadditive). The routes together contain a spanning forest of the chosen stops rooted at the
    starts, at least W long: the minimum spanning tree with every start merged into one root and the
    gap distances |p_a − p_b| ≥ |t_a − t_b| − ρ_a − ρ_b, |s_k − p_a| ≥ |s_k − t_a| − ρ_a. The
    makespan is ≥ the teams' mean time ≥ (Σ g(L_k) + K·h) / m ≥ (g(W) + K·h) / m.
    """
    xy = np.array([q[:2] for q in problem.positions()], dtype=float).reshape(-1, 2)
    reach = ground_reach(problem)
    chosen: list[int] = []
    for i in np.argsort(reach, kind="stable"):  # smallest discs first: more of them fit
        if all(np.linalg.norm(xy[i] - xy[j]) > reach[i] + reach[j] for j in chosen):
            chosen.append(int(i))
    handling = min(problem.stop_time(k) for k in range(problem.n_teams))
    k, m = len(chosen), problem.n_teams
    drive = min(leg_time(_forest_length(problem, xy[chosen], reach[chosen]), p.carrier.motion)
                for p in problem.problems)
    return max(math.ceil(k / m) * handling, (drive + k * handling) / m)


def _forest_length(problem: TeamsProblem, pts: np.ndarray, r: np.ndarray) -> float:
    starts = np.array([s[:2] for s in problem.starts()], dtype=float).reshape(-1, 2)
    n = len(pts)
    w = np.zeros((n + 1, n + 1))
    to_root = np.linalg.norm(pts[:, None] - starts[None], axis=2).min(axis=1) - r
    w[0, 1:] = np.maximum(to_root, 0.0)
    w[1:, 1:] = np.maximum(np.linalg.norm(pts[:, None] - pts[None], axis=2) - r[:, None] - r[None, :], 0.0)
    return mst_length(np.maximum(w, w.T))
