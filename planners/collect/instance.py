"""Per-problem caches of a collection (dissertation ch. 5): rover ground positions, reach radii
and cluster regions, and the check that every rover can be collected at all."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from planners.collect.reach import Point2, Region, make_region, rover_rows
from planners.core.geometry import enclosing_circles
from planners.core.problem import CollectProblem, PlanningError
from planners.core.timing import RANGE_MARGIN


class CollectInstance:
    """Per-problem caches: rover ground positions, reach radii and cluster regions by membership."""

    def __init__(self, problem: CollectProblem) -> None:
        check_rovers(problem)
        self.problem = problem
        rovers = problem.rovers
        self.ground = np.array([[r.position[0], r.position[1]] for r in rovers], dtype=float).reshape(-1, 2)
        z = np.array([r.position[2] for r in rovers], dtype=float)
        self.heights2 = z * z
        rng = np.array([r.range for r in rovers], dtype=float)
        # Reach radius on the ground, kept RANGE_MARGIN inside the range (timing.RANGE_MARGIN).
        self.radii = np.sqrt(np.maximum(np.maximum(rng - RANGE_MARGIN, 0.0) ** 2 - self.heights2, 0.0))
        self.pts2: list[Point2] = [(float(x), float(y)) for x, y in self.ground.tolist()]
        self.rad: list[float] = self.radii.tolist()  # the same numbers as lists, for Python loops
        self.h2: list[float] = self.heights2.tolist()
        self._rows = rover_rows((self.pts2, self.rad, self.h2))  # every rover's disc and row, made once
        self._regions: dict[tuple[int, ...], Region] = {}
        # power and time centres' circles, derived from neighbouring clusters' (core.geometry)
        self._circles = (enclosing_circles(self.pts2), enclosing_circles(self.pts2))

    def region(self, members: Sequence[int], near: Sequence[Sequence[int]] = ()) -> Region:
        """The region of a cluster; ``near``: clusters that may be one member away (a move's old
        clusters), whose circles the new region's are derived from when exact."""
        key = tuple(sorted(members))
        reg = self._regions.get(key)
        if reg is None:
            hints = tuple(tuple(sorted(c)) for c in near)
            reg = make_region(key, self.ground, self.radii, self.heights2, None, self._circles, hints,
                              self._rows)
            self._regions[key] = reg
        return reg

    def fits(self, members: Sequence[int]) -> bool:
        """GET_INTERPTS of Algorithm 5.1 is non-empty: the cluster's reach discs intersect."""
        key = tuple(sorted(members))
        reg = self._regions.get(key)
        if reg is not None:
            return reg.feasible
        if len(members) > 1:  # cheap necessary test: the last rover's disc meets every other disc
            pts, rad = self.pts2, self.rad
            last = members[-1]
            (lx, ly), lr = pts[last], rad[last] + 1e-9
            for i in members[:-1]:
                x, y = pts[i]
                if math.hypot(x - lx, y - ly) - rad[i] > lr:
                    return False
        return self.region(key, (members[:-1],)).feasible  # the moves add a rover last


def check_rovers(problem: CollectProblem) -> None:
    """Reject rovers no plan can collect, by id: a rover must at least be able to land below itself."""
    seen: set[str] = set()
    for r in problem.rovers:
        if r.id in seen:
            raise PlanningError(f"rover {r.id} is listed twice in the collection; give each rover once")
        seen.add(r.id)
        z = r.position[2]
        if z < 0:
            raise PlanningError(f"rover {r.id} is below the ground (z = {z:g} m); heights are above ground")
        if not r.range >= z:
            raise PlanningError(
                f"rover {r.id} cannot be collected: it hovers {z:g} m up with only {r.range:g} m of range "
                f"left, so it cannot even land below itself; it needs a range of at least {z:g} m")
