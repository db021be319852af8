"""Which tasks a launched rover works in one sortie: the longest task left first (longest
processing time first balances the rovers' finishing times), then the nearest tasks left while
the battery, with a margin for waiting to be picked up, and the policy's work cap allow."""

from __future__ import annotations

import math
from collections.abc import Sequence

from planners.core.problem import PlanningError, Vec3
from planners.operations.problem import OperationProblem, OpTask
from planners.operations.schedule import EPS, Chain, chain_profile, return_air

NEAREST = 6  # candidate next tasks tried per extension


def fits(chain: Chain, stop: Vec3, problem: OperationProblem, margin: float) -> bool:
    """The chain and its flight back to ``stop`` fit a battery with ``margin`` s to spare."""
    need = chain.air_to_end + return_air(chain.last, chain.ground, stop, problem)
    return need + margin <= problem.air_budget - EPS


def build_chain(stop: Vec3, left: list[OpTask], problem: OperationProblem, margin: float,
                cap: float) -> Chain:
    """A chain for one rover launched at ``stop`` from ``left`` (longest first; not modified)."""
    first = left[0]
    chain = chain_profile(stop, [first], problem)
    if not fits(chain, stop, problem, 0.0):
        raise PlanningError(f"task {first.id!r} ({first.duration:g} s of work) does not fit one battery "
                            "with the flights to it and back")
    rest = [t for t in left[1:]]
    work = first.duration
    while rest:
        rest.sort(key=lambda t: math.dist(t.position, chain.last))
        for cand in rest[:NEAREST]:
            if work + cand.duration > cap:
                continue
            trial = chain_profile(stop, [*chain.tasks, cand], problem)
            if fits(trial, stop, problem, margin):
                chain, work = trial, work + cand.duration
                rest.remove(cand)
                break
        else:
            break
    return chain


def assign(stop: Vec3, rovers: Sequence[str], left: list[OpTask], problem: OperationProblem,
           margin: float, cap: float) -> list[tuple[str, Chain]]:
    """Chains for ``rovers`` launched together at ``stop``, taken from ``left`` (not modified)."""
    pool = list(left)
    out: list[tuple[str, Chain]] = []
    for r in rovers:
        if not pool:
            break
        chain = build_chain(stop, pool, problem, margin, cap)
        out.append((r, chain))
        taken = {t.id for t in chain.tasks}
        pool = [t for t in pool if t.id not in taken]
    return out
