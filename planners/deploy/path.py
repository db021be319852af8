"""GET_DEPLOY_PATH and CALC_TIME of Algorithm 4.1–4.2 (dissertation ch. 4.4): the path builder
that places a stop per cluster, and the timed route it builds."""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np

from planners.core.geometry import find_root, minimize_1d
from planners.core.native import kernels
from planners.core.problem import Point2
from planners.core.timing import carrier_hopper, leg_timer
from planners.deploy.cluster import ClusterGeometry, DeployInstance, lerp, max_range_point
from planners.deploy.screen import screen


class PathBuilder:
    """GET_DEPLOY_PATH and CALC_TIME of Algorithm 4.1–4.2 for ordered lists of clusters."""

    def __init__(self, inst: DeployInstance) -> None:
        self.inst = inst
        p = inst.problem
        self.carrier, self.rover = p.carrier, p.rover
        self.unload = p.carrier.deploy_stop_time
        self.start: Point2 = (p.start[0], p.start[1])
        # the time model's hop and rover flight with this problem's numbers bound (the same floats)
        self.drive = carrier_hopper(self.carrier)
        self.leg = leg_timer(self.rover)

    def finish(self, pos: Point2, members: Sequence[int]) -> float:
        """Rover flight time to the cluster's farthest task from ``pos`` (eq. 4.5)."""
        return self.leg(self.inst.reach_from(pos, members))

    def place(self, clusters: Sequence[Sequence[int]], geos: Sequence[ClusterGeometry], k: int,
              prev: Point2, t: float, heading: float, worst: float, fine: bool) -> Point2:
        """Deployment point of cluster k given the carrier's state after the previous stop."""
        if k < len(clusters) - 2:
            return max_range_point(prev, geos[k], geos[k + 1].center)
        return self._best_on_segment(prev, t, heading, worst, clusters, geos, k, fine)

    def _best_on_segment(self, prev: Point2, t: float, heading: float, worst: float,
                         clusters: Sequence[Sequence[int]], geos: Sequence[ClusterGeometry], k: int,
                         fine: bool) -> Point2:
        """The last two clusters (eq. 4.14–4.20): slide the stop along prev → centre so that this
        cluster's rovers and the next stop's rovers finish as early as possible, never beyond
        d_deploy. Solved on the exact time model instead of the linearised rotation of eq. 4.16."""
        center = geos[k].center
        s_lo = self.inst.feasible_from(prev, center, clusters[k])
        last = k == len(clusters) - 1
        nxt = None if last else geos[k + 1].center

        def last_stop(pos: Point2, h: float, t1: float, u: float, nxt: Point2) -> float:
            q = lerp(pos, nxt, u)
            dt2, _ = self.drive(pos, q, h)
            return t1 + dt2 + self.unload + self.finish(q, clusters[k + 1])

        seen: dict[tuple[float, float], tuple[float, float]] = {}  # the searches revisit their ends

        def both(s: float, u: float = 1.0) -> tuple[float, float]:
            """This cluster's last arrival and the next (last) cluster's, with the stop at s."""
            got = seen.get((s, u))
            if got is not None:
                return got
            pos = lerp(prev, center, s)
            dt, h = self.drive(prev, pos, heading)
            t1 = t + dt + self.unload
            later = last_stop(pos, h, t1, u, nxt) if nxt is not None else 0.0
            got = seen[(s, u)] = (t1 + self.finish(pos, clusters[k]), later)
            return got

        def makespan(s: float, u: float = 1.0) -> float:
            a, b = both(s, u)  # max(worst, a, b), written out
            m = a if a > worst else worst
            return b if b > m else m

        if not fine and nxt is not None:
            # Eq. 4.20: both clusters' rovers arrive together. This cluster finishes later as the
            # stop moves back toward the carrier, the next one earlier: find the crossing.
            def gap(x: float) -> float:
                a, b = both(x)
                return a - b

            cands = [s_lo, 1.0]
            g_lo, g_hi = gap(s_lo), gap(1.0)
            if g_lo * g_hi < 0:
                cands.append(find_root(gap, s_lo, 1.0, xtol=1e-4))
            return lerp(prev, center, min(cands, key=makespan))

        def best_s(u: float) -> tuple[float, float]:
            s, best = minimize_1d(lambda x: makespan(x, u), s_lo, 1.0, samples=24 if fine else 6,
                                  tol=1e-7 if fine else 2e-3)
            for cand in (s_lo, 1.0):
                if makespan(cand, u) <= best:
                    s, best = cand, makespan(cand, u)
            return s, best

        s, best = best_s(1.0)
        if fine and nxt is not None:
            # The last stop may stop short of its centre too: place both by coordinate descent on
            # (s, u), u the fraction of the way from this stop to the next centre.
            for _ in range(2):
                pos = lerp(prev, center, s)
                u_lo = self.inst.feasible_from(pos, nxt, clusters[k + 1])
                def along_u(x: float, s: float = s) -> float:
                    return makespan(s, x)

                u, _ = minimize_1d(along_u, u_lo, 1.0, samples=8, tol=1e-7)
                s2, best2 = best_s(u)
                if best2 >= best - 1e-9:
                    break
                s, best = s2, best2
        return lerp(prev, center, s)

    def route(self, clusters: list[list[int]], fine: bool = False) -> Route:
        """GET_DEPLOY_PATH for every cluster, then the route's times."""
        geos = [self.inst.geometry(c) for c in clusters]
        positions: list[Point2] = []
        hops: list[float] = []
        headings: list[float] = []
        flies: list[float] = []
        prev, t, heading, worst = self.start, 0.0, self.inst.problem.heading, 0.0
        for k in range(len(clusters)):
            pos = self.place(clusters, geos, k, prev, t, heading, worst, fine)
            dt, heading = self.drive(prev, pos, heading)
            fly = self.finish(pos, clusters[k])
            t += dt + self.unload
            done = t + fly
            if done > worst:  # (max(worst, done), written out)
                worst = done
            positions.append(pos)
            hops.append(dt)
            headings.append(heading)
            flies.append(fly)
            prev = pos
        return Route.timed(self, clusters, geos, positions, hops, headings, flies)


NUMPY_FROM = 24  # stops: from this many on, a route's times are summed with numpy

# a scored change: makespan, clusters, their geometry, stops, first re-placed stop, end of the
# re-placed stops, the old index of the first kept stop
Candidate = tuple[float, list[list[int]], list[ClusterGeometry], list[Point2], int, int, int]


class Route:
    """An ordered cluster list with its stops and the times needed to re-time a local change.

    ``hop[j]`` is the carrier's rotation + drive into stop j, ``heading[j]`` its heading on
    arrival, ``fly[j]`` the flight of stop j's farthest rover; from them (``_times``):
    ``arrive[j]`` the carrier's arrival at stop j, ``done[j]`` when stop j's last rover reaches its
    task, ``tail[j]`` = max(done[j:]), ``head[j]`` = max(done[:j + 1]). A local change drives only
    the hops whose length or turn changed; later stops keep their hops and flights and shift in
    time, so re-timing costs a few hops plus C-speed prefix sums.
    """

    arrive: list[float]
    done: list[float]
    tail: list[float]
    head: list[float]

    def __init__(self, b: PathBuilder, clusters: list[list[int]], geos: list[ClusterGeometry],
                 positions: list[Point2]) -> None:
        self.b, self.clusters, self.geos, self.positions = b, clusters, geos, positions
        self.hop: list[float] = []
        self.heading: list[float] = []
        self.fly: list[float] = []
        prev, h = b.start, b.inst.problem.heading
        for members, pos in zip(clusters, positions, strict=True):
            dt, h = b.drive(prev, pos, h)
            self.hop.append(dt)
            self.heading.append(h)
            self.fly.append(b.finish(pos, members))
            prev = pos
        self._times()

    @classmethod
    def timed(cls, b: PathBuilder, clusters: list[list[int]], geos: list[ClusterGeometry],
              positions: list[Point2], hop: list[float], heading: list[float], fly: list[float]) -> Route:
        """The route of ``positions`` whose hops, headings and flights the caller drove already
        (the same numbers ``__init__`` computes, in the same order)."""
        r = object.__new__(cls)
        r.b, r.clusters, r.geos, r.positions = b, clusters, geos, positions
        r.hop, r.heading, r.fly = hop, heading, fly
        r._times()
        return r

    def _times(self) -> None:
        """The times from the hops and flights: a cumulative sum and running maxima (numpy, the
        same sums in the same order as a loop over the stops)."""
        self.arrive, self.done, self.tail, self.head = _deploy_times(self.hop, self.fly, self.b.unload)
        self.makespan = self.tail[0] if self.tail else 0.0

    def _redrive(self, r: Route, lo: int, hi: int, m: int) -> None:
        """Fill ``r``'s hops, headings and flights: kept before ``lo``, new for the stops lo..hi-1,
        and from ``hi`` on the old stops from ``m`` on, driven again while their turn changed."""
        b = self.b
        r.hop, r.heading, r.fly = self.hop[:lo], self.heading[:lo], self.fly[:lo]
        if lo == 0:
            prev, h = b.start, b.inst.problem.heading
        else:
            prev, h = r.positions[lo - 1], self.heading[lo - 1]
        for j in range(lo, len(r.positions)):
            o = j - hi + m  # the old index of a kept stop
            if j > hi and h == self.heading[o - 1]:  # the rest is driven as before
                r.hop += self.hop[o:]
                r.heading += self.heading[o:]
                r.fly += self.fly[o:]
                break
            pos = r.positions[j]
            dt, h = b.drive(prev, pos, h)
            r.hop.append(dt)
            r.heading.append(h)
            r.fly.append(b.finish(pos, r.clusters[j]) if j < hi else self.fly[o])
            prev = pos
        r._times()

    def moved(self, k: int, q: Point2) -> Route:
        """This route with stop k moved to ``q``: only the hops into k, k + 1 and k + 2 (its turn)
        are driven again; the other stops keep their hops and flights."""
        r = object.__new__(type(self))
        r.b, r.clusters, r.geos = self.b, self.clusters, self.geos
        r.positions = [*self.positions[:k], q, *self.positions[k + 1:]]
        self._redrive(r, k, k + 1, k + 1)
        return r

    def with_stops(self, new: dict[int, Point2]) -> Route:
        """This route with each stop k of ``new`` moved to ``new[k]``: the same route as
        ``Route(b, clusters, geos, positions)``, but only the hops into a moved stop and the one
        after it (and any later hop whose turn changed) are driven again, only moved stops' flights
        measured again."""
        b = self.b
        r = object.__new__(type(self))
        r.b, r.clusters, r.geos = b, self.clusters, self.geos
        r.positions = pos = list(self.positions)
        for k, q in new.items():
            pos[k] = q
        r.hop, r.heading, r.fly = list(self.hop), list(self.heading), list(self.fly)
        for j in range(min(new, default=len(pos)), len(pos)):
            h = r.heading[j - 1] if j else b.inst.problem.heading
            if j in new or j - 1 in new or (j and h != self.heading[j - 1]):
                r.hop[j], r.heading[j] = b.drive(pos[j - 1] if j else b.start, pos[j], h)
                if j in new:
                    r.fly[j] = b.finish(pos[j], self.clusters[j])
        r._times()
        return r

    def accept(self, cand: Candidate) -> Route:
        """The route of a scored change (``replace``): stops before ``lo`` and from old stop ``m``
        on keep their hops and flights; only the changed stops and the turns after them are driven."""
        _, clusters, geos, positions, lo, hi, m = cand
        r = object.__new__(type(self))
        r.b, r.clusters, r.geos, r.positions = self.b, clusters, geos, positions
        self._redrive(r, lo, hi, m)
        return r

    def screen(self, changes: Sequence[tuple[int, list[list[int]], int]]) -> np.ndarray:
        """A lower bound of ``replace(*change)[0]`` for every change, all at once with numpy
        (−inf where it does not know; ``planners.deploy.screen``)."""
        return screen(self, changes)

    def replace(self, i: int, pieces: list[list[int]], count: int = 1) -> Candidate:
        """Makespan after clusters i..i+count-1 are replaced by ``pieces``, recomputing the stops
        around the change (the one before, the pieces, the one after) and keeping later stops."""
        b, old = self.b, self.clusters
        clusters = old[:i] + pieces + old[i + count:]
        geos = self.geos[:i] + [b.inst.geometry(p) for p in pieces] + self.geos[i + count:]
        lo = max(i - 1, 0)
        hi = i + len(pieces) + 1  # first new index kept from the old route (exclusive window end)
        if hi >= len(clusters) - 2:
            hi = len(clusters)  # the last two clusters are placed together (eq. 4.20)
        if lo == 0:
            prev, t, h, worst = b.start, 0.0, b.inst.problem.heading, 0.0
        else:
            prev = self.positions[lo - 1]
            t, h = self.arrive[lo - 1] + b.unload, self.heading[lo - 1]
            worst = self.head[lo - 1]
        positions = self.positions[:lo]
        place, drive, unload, finish = b.place, b.drive, b.unload, b.finish
        for k in range(lo, hi):
            pos = place(clusters, geos, k, prev, t, h, worst, fine=False)
            dt, h = drive(prev, pos, h)
            t += dt + unload
            done = t + finish(pos, clusters[k])
            if done > worst:  # (max(worst, done), written out)
                worst = done
            positions.append(pos)
            prev = pos
        m = hi - len(pieces) + count  # old index of the first kept stop
        if m < len(old):
            pos = self.positions[m]
            dt, h = b.drive(prev, pos, h)
            t += dt + b.unload
            done = t + self.fly[m]  # the kept stop's flight: b.finish(pos, old[m])
            if done > worst:
                worst = done
            if m + 1 < len(old):
                dt, _ = b.drive(pos, self.positions[m + 1], h)
                shift = t + dt - self.arrive[m + 1]
                done = self.tail[m + 1] + shift
                if done > worst:
                    worst = done
            positions += self.positions[m:]
        return worst, clusters, geos, positions, lo, hi, m


def deploy_times(hop: Sequence[float], fly: Sequence[float],
                 unload: float) -> tuple[list[float], list[float], list[float], list[float]]:
    """``Route._times``: per stop the carrier's arrival, when its rovers are done, and the running
    maxima of done from the end (tail) and from the start (head)."""
    if len(hop) < NUMPY_FROM:  # short routes: plain Python is faster than numpy's calls
        departs = list(itertools.accumulate(h + unload for h in hop))
        done = [d + f for d, f in zip(departs, fly, strict=True)]
        return ([d - unload for d in departs], done, list(itertools.accumulate(reversed(done), max))[::-1],
                list(itertools.accumulate(done, max)))
    depart = np.cumsum(np.array(hop) + unload)
    done_a = depart + np.array(fly)
    return ((depart - unload).tolist(), done_a.tolist(), np.maximum.accumulate(done_a[::-1])[::-1].tolist(),
            np.maximum.accumulate(done_a).tolist())


# the compiled twin when it is built (planners.core.native): the same floats
_deploy_times = deploy_times if kernels is None else kernels.deploy_times
