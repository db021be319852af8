"""GET_COLLECT_PATH and CALC_TIME of Algorithm 5.1–5.2 (dissertation ch. 5): the path builder that
places a stop per cluster of rovers, and the timed route it builds."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence

import numpy as np

from planners.collect.instance import CollectInstance
from planners.collect.reach import Point2, Region, farthest_flight
from planners.collect.screen import screen
from planners.core.geometry import minimize_1d
from planners.core.native import kernels
from planners.core.timing import Step, carrier_hopper, carrier_stepper, leg_timer

Scored = tuple[Point2, float, float, float | None]  # a quick candidate: stop, hop in, heading, hop on


class PathBuilder:
    """GET_COLLECT_PATH and CALC_TIME of Algorithm 5.1–5.2 for ordered lists of clusters."""

    def __init__(self, inst: CollectInstance) -> None:
        self.inst = inst
        p = inst.problem
        self.carrier, self.rover = p.carrier, p.rover
        self.load = p.carrier.collect_stop_time
        self.start: Point2 = (p.start[0], p.start[1])
        self.heading0 = p.heading
        # the time model's hop, step and rover flight with this problem's numbers bound (the same floats)
        self.step = carrier_stepper(self.carrier)
        self.drive = carrier_hopper(self.carrier)
        self.leg = leg_timer(self.rover)
        # whether Route.replace places the stop before a change afresh too (the quick descent of
        # long routes leaves it where it is: ``planners.collect.lee.QD_KEEP_BEFORE_FROM``)
        self.replace_before = True
        # ``_quick``'s candidates by region, previous stop, heading and next stop
        self._scored: dict[tuple, tuple[Scored, ...]] = {}
        self._caps: dict[tuple[int, ...], float] = {}  # ``_ready_cap`` by membership
        # per rover: the squared flight to the farthest point of its reach disc, with READY_SLACK
        self._reach2 = [(r + READY_SLACK) ** 2 + z2 for r, z2 in zip(inst.rad, inst.h2, strict=True)]

    def ready(self, region: Region, p: Point2) -> float:
        """g(q_γ) of eq. 5.2: when the cluster's last rover lands at ``p`` (all leave at t = 0)."""
        return self.leg(region.farthest_flight(p))

    def local_time(self, region: Region, p: Point2, prev: Point2, t: float, heading: float,
                   nxt: Point2 | None) -> float:
        """η_β of eq. 5.2 at ``p`` plus the hop on to the next stop: what placing q_γβ at p costs."""
        dt, h = self.drive(prev, p, heading)
        eta = max(t + dt, self.leg(region.farthest_flight(p))) + self.load
        if nxt is not None:
            eta += self.drive(p, nxt, h)[0]
        return eta

    def place(self, region: Region, prev: Point2, t: float, heading: float, nxt: Point2 | None,
              level: int = 0) -> Point2:
        """Collection location of one cluster given the carrier's state after the previous stop.

        Level 0 (the clustering search) scores a few points: the time centre, the point nearest
        the previous stop and the carrier's line point (eq. 5.13). Levels 1–2 score the chapter's
        full candidate set (Fig. 5.6: the circles' intersection points, eq. 5.13–5.16) and slide the
        best toward the time centre and the line point (level 2: toward every candidate); I_β is
        convex, so every such segment stays inside it.
        """
        if level == 0:
            return self.quick_place(region, prev, t, heading, nxt)[0]
        step, leg, load = self.step, self.leg, self.load
        cap = self._cap(region)

        def cost(p: Point2) -> float:
            """``local_time`` at ``p`` (the same floats): the candidates and the points between
            them lie in I_β, so a rover's flight is needed only while the carrier could be early."""
            dt, h = step(p[0] - prev[0], p[1] - prev[1], heading)
            arrive = t + dt
            if arrive < cap:
                arrive = max(arrive, leg(region.farthest_flight(p)))
            eta = arrive + load
            if nxt is not None:
                eta += step(nxt[0] - p[0], nxt[1] - p[1], h)[0]
            return eta

        cands = region.candidates(prev, nxt)
        vals = [cost(p) for p in cands]
        j = min(range(len(cands)), key=vals.__getitem__)
        best, best_v = cands[j], vals[j]
        targets = cands if level >= 2 else [region.time_center, region.line_point(prev, nxt)]
        for q in targets:
            if math.dist(q, best) < 1e-6:
                continue
            a = best

            def along(s: float, a: Point2 = a, q: Point2 = q) -> float:
                return cost((a[0] + s * (q[0] - a[0]), a[1] + s * (q[1] - a[1])))

            s, v = minimize_1d(along, 0.0, 1.0, samples=8 if level >= 2 else 4,
                               tol=1e-7 if level >= 2 else 1e-4)
            if v < best_v:
                best, best_v = (a[0] + s * (q[0] - a[0]), a[1] + s * (q[1] - a[1])), v
        return best

    def quick_place(self, region: Region, prev: Point2, t: float, heading: float,
                    nxt: Point2 | None) -> tuple[Point2, float, float, float]:
        """``place`` at level 0 with what it timed on the way: the stop, the hop into it (time and
        heading on arrival) and when the cluster's last rover lands there (``local_time`` of
        each quick candidate, the first fastest kept; the same floats)."""
        (p, dt, h, _), _ = self._quick(region, prev, t, heading, nxt)
        return p, dt, h, self.leg(region.farthest_flight(p))

    def _quick(self, region: Region, prev: Point2, t: float, heading: float,
               nxt: Point2 | None) -> tuple[Scored, float]:
        """``quick_place``'s fastest candidate (stop, hop time, heading, hop on) and
        max(t + hop time, ready): eq. 5.2's departure less the load (``replace`` goes on from it).

        A candidate's hops do not depend on ``t``: they are remembered per region, previous stop,
        heading and next stop (the descent scores the same stops again as other stops move). Its
        rovers' ready time is only needed while the carrier could arrive before the last of them:
        once t + hop ≥ the region's ``_ready_cap`` the max is t + hop whatever the ready time."""
        key = (region.members, prev, heading, nxt)
        scored = self._scored.get(key)
        if scored is None:
            if len(self._scored) >= SCORED_SIZE:
                self._scored.clear()
            scored = self._scored[key] = self._score(region, prev, heading, nxt)
        return _quickest(scored, t, self._cap(region), self.leg, region.rows, self.load)

    def _score(self, region: Region, prev: Point2, heading: float, nxt: Point2 | None) -> tuple[Scored, ...]:
        """Per quick candidate: (stop, hop time into it, heading there, hop time on to ``nxt`` or
        None), ``carrier_stepper``'s arithmetic as ``drive``'s (tuples of numbers: the garbage
        collector stops tracking them)."""
        return _score_candidates(self.step, region.quick_candidates(prev, nxt), prev, heading, nxt)

    def _cap(self, region: Region) -> float:
        """``_ready_cap`` of ``region``, remembered."""
        cap = self._caps.get(region.members)
        if cap is None:
            cap = self._caps[region.members] = self._ready_cap(region)
        return cap

    def _ready_cap(self, region: Region) -> float:
        """A time no rover of ``region`` lands after at any quick candidate: every candidate lies in
        the reach discs (up to rounding, far below ``READY_SLACK``), so its flight is at most
        sqrt((ρ + slack)² + z²); inf for an empty region (its candidates may lie anywhere)."""
        if not region.feasible:
            return math.inf
        reach2 = self._reach2
        return self.leg(math.sqrt(max([reach2[i] for i in region.members]))) + READY_SLACK

    def route(self, clusters: list[list[int]], level: int = 0) -> Route:
        """GET_COLLECT_PATH for every cluster in order, then the route's times (CALC_TIME)."""
        regions = [self.inst.region(c) for c in clusters]
        positions: list[Point2] = []
        hops: list[float] = []
        headings: list[float] = []
        readies: list[float] = []
        prev, t, heading = self.start, 0.0, self.heading0
        for k, reg in enumerate(regions):
            nxt = regions[k + 1].center if k + 1 < len(regions) else None  # next stop not known yet
            if level == 0:
                pos, dt, heading, ready = self.quick_place(reg, prev, t, heading, nxt)
            else:
                pos = self.place(reg, prev, t, heading, nxt, level)
                ready = self.ready(reg, pos)
                dt, heading = self.drive(prev, pos, heading)
            t = max(t + dt, ready) + self.load
            positions.append(pos)
            hops.append(dt)
            headings.append(heading)
            readies.append(ready)
            prev = pos
        return Route(self, clusters, regions, positions, (hops, headings, readies))


# ``PathBuilder._quick``'s remembered candidates, then it starts afresh (a 1000-rover quick plan: ~5,000)
SCORED_SIZE = 20_000
READY_SLACK = 1e-3  # m (and s): ``PathBuilder._ready_cap``'s headroom over rounding

NUMPY_FROM = 24  # stops: from this many on, a route's times are summed with numpy

# a scored change: makespan, the change (i, pieces, count), the first re-placed stop, the regions
# and stops placed afresh (the route's lists are built only when the change is accepted)
Candidate = tuple[float, int, list[list[int]], int, int, list[Region], list[Point2]]


class Route:
    """An ordered cluster list with its stops and the times eq. 5.2 gives them.

    ``hop[j]`` is the carrier's rotation + drive into stop j, ``heading[j]`` its heading on arrival,
    ``ready[j]`` when stop j's last rover lands, ``eta[j]`` the departure from stop j.
    """

    def __init__(self, b: PathBuilder, clusters: list[list[int]], regions: list[Region],
                 positions: list[Point2], timed: tuple[list[float], list[float], list[float]] | None = None,
                 ) -> None:
        """``timed``: ``hop``, ``heading`` and ``ready`` when the caller drove the route already."""
        self.b, self.clusters, self.regions, self.positions = b, clusters, regions, positions
        if timed is not None:
            self.hop, self.heading, self.ready = timed
            self._times()
            return
        self.hop = []
        self.heading = []
        self.ready = []
        prev, h = b.start, b.heading0
        for reg, pos in zip(regions, positions, strict=True):
            dt, h = b.drive(prev, pos, h)
            self.hop.append(dt)
            self.heading.append(h)
            self.ready.append(b.ready(reg, pos))
            prev = pos
        self._times()

    def _times(self) -> None:
        """``eta`` and the makespan from ``hop`` and ``ready`` (eq. 5.2), and the suffix sums.

        Eq. 5.2 is max-plus linear in a departure time: leaving stop j at t, the route ends at
        max(t + after[j], late[j]) (after: hops and loads still to come; late: the latest a later
        cluster's rovers hold the carrier up), so re-timing a local change costs O(1).
        With S_j the hops and loads up to stop j and v_j = ready_j + load − S_j, the departures are
        eta_j = S_j + max(0, v_0 … v_j) and, S the total, after_j = S − S_j, late_j = S + max(v_j+1 …):
        prefix sums and running maxima, no Python loop over the stops."""
        if not self.hop:
            self.eta, self.makespan, self.after, self.late = [], 0.0, [], []
            return
        self.eta, self.after, self.late = _route_times(self.hop, self.ready, self.b.load)
        self.makespan = self.eta[-1]

    def moved(self, k: int, q: Point2) -> Route:
        """This route with stop k moved to ``q``: only the hops whose turn or length changed (into
        k, k + 1, k + 2 and on while the arrival heading differs) are driven again."""
        b = self.b
        r = object.__new__(type(self))
        r.b, r.clusters, r.regions = b, self.clusters, self.regions
        r.positions = [*self.positions[:k], q, *self.positions[k + 1:]]
        r.hop, r.heading, r.ready = self.hop[:], self.heading[:], self.ready[:]
        r.ready[k] = b.ready(self.regions[k], q)
        prev, h = (b.start, b.heading0) if k == 0 else (self.positions[k - 1], self.heading[k - 1])
        for j in range(k, len(r.positions)):
            if j > k + 1 and h == self.heading[j - 1]:
                break
            r.hop[j], h = b.drive(prev, r.positions[j], h)
            r.heading[j] = h
            prev = r.positions[j]
        r._times()
        return r

    def end_from(self, j: int, t: float) -> float:
        """Makespan when the carrier leaves stop j at ``t`` and later stops keep their places."""
        end, late = t + self.after[j], self.late[j]
        return late if late > end else end  # (max(end, late), written out)

    def state_before(self, k: int) -> tuple[Point2, float, float]:
        """Carrier position, time and heading when it leaves the stop before stop k."""
        if k == 0:
            return self.b.start, 0.0, self.b.heading0
        return self.positions[k - 1], self.eta[k - 1], self.heading[k - 1]

    def _finish(self, m: int, prev: Point2, t: float, h: float) -> float:
        """Makespan when the carrier leaves ``prev`` at ``t`` with heading ``h`` for old stop m."""
        b = self.b
        last = min(m + 2, len(self.positions))
        for j in range(m, last):  # the heading into m changed, so the rotation at m (into m + 1) too
            pos = self.positions[j]
            dt, h = b.drive(prev, pos, h)
            t += dt
            ready = self.ready[j]
            t = (ready if ready > t else t) + b.load  # (max(t + dt, ready) + load, written out)
            prev = pos
        return self.end_from(last - 1, t)

    def accept(self, cand: Candidate) -> Route:
        """The route of a scored change: stops before ``lo`` and from old stop ``m`` on keep their
        hops and rovers' times; only the changed stops (and the hops whose heading changed) are
        driven again, so a long route accepts a local change in a few hops."""
        _, i, pieces, count, lo, window, placed = cand
        hi, m = i + len(pieces), i + count  # new stops lo..hi−1, the first kept stop's old index
        b = self.b
        r = object.__new__(type(self))
        r.b = b
        r.clusters = self.clusters[:i] + pieces + self.clusters[m:]
        r.positions = positions = self.positions[:lo] + placed + self.positions[m:]
        r.regions = self.regions[:lo] + window + self.regions[m:]
        r.hop, r.heading, r.ready = self.hop[:lo], self.heading[:lo], self.ready[:lo]
        prev, h = (b.start, b.heading0) if lo == 0 else (positions[lo - 1], self.heading[lo - 1])
        for j in range(lo, len(positions)):
            o = j - hi + m  # the old index of a kept stop
            if j > hi and h == self.heading[o - 1]:  # the rest is driven as before
                r.hop += self.hop[o:]
                r.heading += self.heading[o:]
                r.ready += self.ready[o:]
                break
            dt, h = b.drive(prev, positions[j], h)
            r.hop.append(dt)
            r.heading.append(h)
            r.ready.append(b.ready(r.regions[j], positions[j]) if j < hi else self.ready[o])
            prev = positions[j]
        r._times()
        return r

    def replace(self, i: int, pieces: list[list[int]], count: int = 1) -> Candidate:
        """Makespan after clusters i..i+count-1 are replaced by ``pieces``: the stop before (unless
        the builder's ``replace_before`` is off), the pieces and their stops are placed afresh; later
        stops keep their places and are re-timed."""
        b, n = self.b, len(self.clusters)
        near = self.clusters[i:i + count]
        lo = max(i - 1, 0) if b.replace_before else i
        m = i + count  # old index of the first kept stop
        window = [*self.regions[lo:i], *(b.inst.region(p, near) for p in pieces)]  # stops lo..hi−1
        prev, t, h = self.state_before(lo)
        placed: list[Point2] = []
        for k, reg in enumerate(window):
            if k + 1 < len(window):
                nxt: Point2 | None = window[k + 1].center
            else:
                nxt = self.positions[m] if m < n else None
            (pos, _, h, _), held = b._quick(reg, prev, t, h, nxt)
            t = held + b.load
            placed.append(pos)
            prev = pos
        if m < n:
            t = self._finish(m, prev, t, h)
        return t, i, pieces, count, lo, window, placed

    def screen(self, changes: Sequence[tuple[int, list[list[int]], int]]) -> np.ndarray:
        """A lower bound of ``replace(*change)[0]`` for every change at once (numpy; −inf where it
        has none; ``planners.collect.screen``)."""
        return screen(self, changes)


def route_times(hop: Sequence[float], ready: Sequence[float],
                load: float) -> tuple[list[float], list[float], list[float]]:
    """``Route._times`` of a route of at least one stop: eta, after and late (``late`` ends with
    −inf, nothing after the last stop holds the carrier up)."""
    if len(hop) < NUMPY_FROM:  # short routes: plain Python is faster than numpy's calls
        sums = list(itertools.accumulate(h + load for h in hop))
        v = [r + load - s for r, s in zip(ready, sums, strict=True)]
        held = itertools.islice(itertools.accumulate(v, max, initial=0.0), 1, None)
        eta = [s + u for s, u in zip(sums, held, strict=True)]
        end = sums[-1]
        after = [end - s for s in sums]
        later = list(itertools.accumulate(reversed(v), max))[::-1]
        late = [end + x for x in later[1:]]
    else:
        total = np.cumsum(np.array(hop) + load)
        w = np.array(ready) + load - total
        eta = (total + np.maximum(np.maximum.accumulate(w), 0.0)).tolist()
        end = float(total[-1])
        after = (end - total).tolist()
        late = (end + np.maximum.accumulate(w[::-1])[::-1][1:]).tolist()
    late.append(-math.inf)
    return eta, after, late


def score_candidates(step: Step, cands: Sequence[Point2], prev: Point2, heading: float,
                     nxt: Point2 | None) -> tuple[Scored, ...]:
    """``PathBuilder._score``: per candidate stop (stop, hop time into it from ``prev`` and
    ``heading``, heading there, hop time on to ``nxt`` or None)."""
    out = []
    for p in cands:
        dt, h = step(p[0] - prev[0], p[1] - prev[1], heading)
        out.append((p, dt, h, None if nxt is None else step(nxt[0] - p[0], nxt[1] - p[1], h)[0]))
    return tuple(out)


def quickest(scored: Sequence[Scored], t: float, cap: float, leg: Callable[[float], float],
             rows: Sequence[tuple[float, float, float]], load: float) -> tuple[Scored, float]:
    """``PathBuilder._quick``'s choice: the scored candidate the carrier leaves soonest from (the
    first of equals) when it leaves the previous stop at ``t``, and max(t + hop, ready) there. The
    rovers' ready time (``leg`` of the longest flight from ``rows``) only counts while the carrier
    could arrive before ``cap``."""
    best: Scored | None = None
    best_eta = best_max = math.inf
    for entry in scored:
        arrive = t + entry[1]
        if arrive >= cap:
            held = arrive
        else:  # (max(arrive, ready), written out: the first of equals, as the builtin)
            ready = leg(farthest_flight(rows, entry[0]))
            held = ready if ready > arrive else arrive
        eta = held + load
        if entry[3] is not None:
            eta += entry[3]
        if best is None or eta < best_eta:
            best, best_eta, best_max = entry, eta, held
    if best is None:
        raise ValueError("quickest of no candidates")
    return best, best_max


# the compiled twins when they are built (planners.core.native): the same floats
_score_candidates = score_candidates if kernels is None else kernels.score_candidates
_quickest = quickest if kernels is None else kernels.quickest
_route_times = route_times if kernels is None else kernels.route_times
