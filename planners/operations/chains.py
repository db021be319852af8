"""Which tasks a launched rover works in one sortie: the longest task left that its battery
allows first (longest processing time first balances the rovers' finishing times), then the
nearest tasks left while the battery, with a margin for waiting to be picked up, and the policy's
work cap allow."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from planners.core.problem import Vec3
from planners.operations.problem import OperationProblem, OpTask
from planners.operations.schedule import EPS, Chain, chain_profile, return_air

NEAREST = 6  # candidate next tasks tried per extension


def fits(chain: Chain, stop: Vec3, problem: OperationProblem, margin: float, budget: float) -> bool:
    """The chain and its flight back to ``stop`` fit ``budget`` air seconds with ``margin`` to spare."""
    need = chain.air_to_end + return_air(chain.last, chain.ground, stop, problem)
    return need + margin <= budget - EPS


def build_chain(stop: Vec3, left: list[OpTask], problem: OperationProblem, margin: float, cap: float,
                budget: float) -> Chain | None:
    """A chain from ``left`` (longest first; not modified) for a rover with ``budget`` air seconds,
    or None when no task of ``left`` fits it."""
    singles = (chain_profile(stop, [t], problem) for t in left)
    found = next((c for c in singles if fits(c, stop, problem, 0.0, budget)), None)
    if found is None:
        return None
    chain = found
    rest = [t for t in left if t is not chain.tasks[0]]
    work = chain.tasks[0].duration
    while rest:
        rest.sort(key=lambda t: math.dist(t.position, chain.last))
        for cand in rest[:NEAREST]:
            if work + cand.duration > cap:
                continue
            trial = chain_profile(stop, [*chain.tasks, cand], problem)
            if fits(trial, stop, problem, margin, budget):
                chain, work = trial, work + cand.duration
                rest.remove(cand)
                break
        else:
            break
    return chain


def assign(stop: Vec3, rovers: Sequence[str], left: list[OpTask], problem: OperationProblem, margin: float,
           cap: float, battery: Callable[[str], float]) -> tuple[list[tuple[str, Chain]], list[str]]:
    """Chains for ``rovers`` launched together at ``stop``, taken from ``left`` (not modified), and
    the rovers whose battery (``battery(rover)`` air seconds) fits no task left."""
    pool = list(left)
    out: list[tuple[str, Chain]] = []
    flat: list[str] = []
    for r in rovers:
        if not pool:
            break
        chain = build_chain(stop, pool, problem, margin, cap, battery(r))
        if chain is None:
            flat.append(r)
            continue
        out.append((r, chain))
        taken = {t.id for t in chain.tasks}
        pool = [t for t in pool if t.id not in taken]
    return out, flat
