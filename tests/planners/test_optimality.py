"""``lee`` against the exact reference (planners.core.exact) on tiny instances (n ≤ 3).

The reference tries every ordered partition of the tasks (rovers) into stops and places the
stops by constrained optimisation on the exact time model. Tolerance: ``lee`` may be at most
GAP_TOL (0.2 %) slower than the reference on each instance; on these instances it is within
0.12 % (see bench/optimality.py for the gap table at n = 2–5).
"""

from __future__ import annotations

import pytest

from bench.optimality import collect_instance, deploy_instance  # the bench's instances, seed for seed
from planners import COLLECT_PLANNERS, DEPLOY_PLANNERS
from planners.core.exact import exact_plan
from planners.core.partitions import ordered_partitions

GAP_TOL = 0.002


def test_ordered_partitions_are_the_fubini_numbers() -> None:
    assert [sum(1 for _ in ordered_partitions(n)) for n in range(1, 6)] == [1, 3, 13, 75, 541]


TINY = [(2, 0), (2, 1), (2, 2), (2, 3), (3, 0), (3, 1), (3, 2), (3, 3), (3, 4), (3, 5)]


@pytest.mark.parametrize("n,seed", TINY)
def test_deploy_lee_near_the_reference(n: int, seed: int) -> None:
    problem = deploy_instance(n, seed)
    plan = DEPLOY_PLANNERS["lee"](problem)
    ref = exact_plan(problem, seed=seed, starts=1)
    assert plan.makespan <= ref.makespan * (1 + GAP_TOL) + 1e-6, (plan.makespan, ref.makespan)


@pytest.mark.parametrize("n,seed", TINY)
def test_collect_lee_near_the_reference(n: int, seed: int) -> None:
    problem = collect_instance(n, seed)
    plan = COLLECT_PLANNERS["lee"](problem)
    ref = exact_plan(problem, seed=seed, starts=1)
    assert plan.makespan <= ref.makespan * (1 + GAP_TOL) + 1e-6, (plan.makespan, ref.makespan)
