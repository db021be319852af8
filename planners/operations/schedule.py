"""Building an operation's schedule stop by stop: the carrier's state, the rovers on the deck and
in the air, the swap station. The planner and the waves baseline both build their plans here, so
that every time comes from one place (:mod:`planners.operations.timing`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from planners.core.problem import PlanningError, Vec3
from planners.core.timing import carrier_leg, path_length, time_model_terms
from planners.operations.plan import OperationPlan, OpStop, Sortie, Swap, Visit
from planners.operations.problem import OperationProblem, OpTask
from planners.operations.timing import (
    approach_point,
    flight_time,
    land_start,
    launch_point,
    stop_depart,
    stop_loaded,
)

EPS = 1e-6  # s of battery the planners keep unplanned, so that rounded JSON still checks


@dataclass
class Chain:
    """A sortie's tasks flown from a stop: the air time up to the end of the last task's work,
    the time from departure to then, and where the rover is."""

    tasks: list[OpTask]
    air_to_end: float
    span: float
    last: Vec3
    ground: bool


def chain_profile(stop: Vec3, tasks: Sequence[OpTask], problem: OperationProblem) -> Chain:
    """The times of a chain of tasks flown from ``stop`` (departure at 0)."""
    here, ground, t = launch_point(stop, problem), False, 0.0
    air = problem.carrier.takeoff_time  # the climb clear of the deck, before departure
    for task in tasks:
        fly = flight_time(here, task.position, problem, ground)
        t += fly + task.duration
        air += fly + (0.0 if task.ground else task.duration)
        here, ground = task.position, task.ground
    return Chain(list(tasks), air, t, here, ground)


def return_air(chain_last: Vec3, ground: bool, stop: Vec3, problem: OperationProblem) -> float:
    """Air seconds from the end of the last task's work to touch-down at ``stop``, leaving at once."""
    return flight_time(chain_last, approach_point(stop, problem), problem, ground) + problem.carrier.land_time


@dataclass
class Airborne:
    sortie: Sortie
    last: Vec3
    end: float  # end of the last task's work
    ground: bool  # the last task is worked landed: the rover waits there for free
    air_to_end: float
    used_before: float = 0.0  # s of this battery flown before the sortie (0: launched on a full one)
    release: float = 0.0  # it does not leave its last task before this (the waves' collection start)


class Schedule:
    """The operation so far: append stops; :meth:`finish` gives the plan.

    A rover picked up with less than ``swap_below`` of its battery's air time left gets a swap
    at once (one swap at a time, in pick-up order); the others stay on the deck with what they
    have and get a swap (:meth:`swap`) when a planner needs them full."""

    def __init__(self, problem: OperationProblem, swap_below: float = 1.0) -> None:
        self.p = problem
        self.swap_below = swap_below
        self.used: dict[str, float] = dict.fromkeys(problem.rovers, 0.0)  # air s since the last full battery
        self.pos: Vec3 = (problem.start[0], problem.start[1], 0.0)
        self.heading = problem.heading
        self.free = 0.0  # the carrier's last departure
        self.stops: list[OpStop] = []
        self.sorties: list[Sortie] = []
        self.swaps: list[Swap] = []
        self.ready: dict[str, float] = dict.fromkeys(problem.rovers, 0.0)  # on the deck, battery full at
        self.air: dict[str, Airborne] = {}
        self._swap_free = 0.0
        self._pending: dict[str, int] = {}  # rover -> index of its swap not yet used by a launch

    def drive(self, point: Vec3) -> float:
        return carrier_leg([self.pos, point], self.heading, self.p.carrier)[0]

    def fly_back(self, rover: str, point: Vec3) -> float:
        a = self.air[rover]
        return flight_time(a.last, approach_point(point, self.p), self.p, a.ground)

    def earliest_meet(self, rover: str, point: Vec3) -> float:
        a = self.air[rover]
        return max(a.end, a.release) + self.fly_back(rover, point)

    def air_if_landing(self, rover: str, point: Vec3, start: float) -> float:
        """The sortie's air time if the rover comes down at ``point`` at ``start``."""
        a = self.air[rover]
        if a.ground:  # it waits landed at its task and leaves in time
            return a.air_to_end + self.fly_back(rover, point) + self.p.carrier.land_time
        return a.air_to_end + max(start, self.earliest_meet(rover, point)) - a.end + self.p.carrier.land_time

    def deadline(self, rover: str, point: Vec3) -> float:
        """The latest landing start at ``point`` the rover's battery allows (-inf: none)."""
        a = self.air[rover]
        budget = self.p.air_budget - EPS - a.used_before
        if self.air_if_landing(rover, point, -math.inf) > budget:
            return -math.inf
        if a.ground:
            return math.inf
        return a.end + budget - a.air_to_end - self.p.carrier.land_time

    def add_stop(self, point: Vec3, pickups: Sequence[str], launches: Sequence[tuple[str, Chain]],
                 not_before: float = 0.0) -> OpStop:
        """Drive to ``point`` (not arriving before ``not_before``), pick up, launch."""
        path = [self.pos, point]
        dt, heading = carrier_leg(path, self.heading, self.p.carrier)
        arrive = max(self.free + dt, not_before)
        meets = [self.earliest_meet(r, point) for r in pickups]
        loaded = stop_loaded(arrive, meets, self.p)
        k = len(self.stops)
        for r in pickups:
            self._land(r, point, k, land_start(arrive, meets), loaded)
        depart = stop_depart(loaded, bool(launches), self.p)
        for r, chain in launches:
            self._launch(r, chain, point, k, depart, loaded)
        stop = OpStop(point, path, arrive, loaded, depart, list(pickups), [r for r, _ in launches])
        self.stops.append(stop)
        self.pos, self.heading, self.free = point, heading, depart
        return stop

    def _land(self, rover: str, point: Vec3, k: int, start: float, loaded: float) -> None:
        a = self.air[rover]
        fly = self.fly_back(rover, point)
        s = a.sortie
        s.air_time = self.air_if_landing(rover, point, start)
        used = a.used_before + s.air_time
        if used > self.p.air_budget:
            raise PlanningError(f"rover {rover} would land with {used:.1f} s of its battery flown, more than "
                                f"the {self.p.air_budget:.1f} s above the reserve")
        last = s.visits[-1]
        last.leave = max(last.end, a.release, start - fly)
        s.pickup_stop, s.meet, s.aboard = k, last.leave + fly, loaded
        s.landed = start + self.p.carrier.land_time
        s.battery_left = 1.0 - used / self.p.endurance
        del self.air[rover]
        self.used[rover], self.ready[rover] = used, loaded
        if self.p.air_budget - used < self.swap_below * self.p.air_budget:
            self.swap(rover)

    def swap(self, rover: str) -> None:
        """A fresh battery for a rover on the deck, at the swap station's next free moment."""
        begin = max(self.ready[rover], self._swap_free)
        self._swap_free = begin + self.p.swap_time
        self._pending[rover] = len(self.swaps)
        self.swaps.append(Swap(rover, begin, self._swap_free))
        self.ready[rover], self.used[rover] = self._swap_free, 0.0

    def battery(self, rover: str) -> float:
        """Air seconds a rover on the deck may still fly above its reserve."""
        return self.p.air_budget - self.used[rover]

    def _launch(self, rover: str, chain: Chain, point: Vec3, k: int, depart: float, loaded: float) -> None:
        assert self.ready[rover] <= loaded + 1e-9, (rover, self.ready[rover], loaded)
        del self.ready[rover]
        self._pending.pop(rover, None)
        t, here, ground, visits = depart, launch_point(point, self.p), False, []
        for task in chain.tasks:
            arrive = t + flight_time(here, task.position, self.p, ground)
            t = arrive + task.duration
            visits.append(Visit(task.id, task.position, arrive, t, t, task.ground))
            here, ground = task.position, task.ground
        s = Sortie(rover, k, depart - self.p.carrier.takeoff_time, depart, visits,
                   battery_start=1.0 - self.used[rover] / self.p.endurance)
        self.sorties.append(s)
        self.air[rover] = Airborne(s, here, t, ground, chain.air_to_end, self.used[rover])

    def finish(self, planner: str) -> OperationPlan:
        """The plan (every rover must be back); swaps never followed by a launch are left out."""
        assert not self.air, f"rovers still in the air: {sorted(self.air)}"
        unused = set(self._pending.values())
        swaps = [w for i, w in enumerate(self.swaps) if i not in unused]
        plan = OperationPlan(planner, self.p.start, self.p.heading, self.stops, self.sorties, swaps,
                             makespan=self.free,
                             carrier_distance=sum(path_length(s.carrier_path) for s in self.stops))
        plan.time_model = {**time_model_terms(self.p.carrier, self.p.rover), "swap_time": self.p.swap_time,
                           "takeoff_height": self.p.takeoff_height, "approach_height": self.p.approach_height,
                           "endurance": self.p.endurance, "reserve": self.p.reserve}
        return plan
