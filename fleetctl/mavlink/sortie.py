"""An operation's missions (docs/mavlink.md, "Operation missions"): the carrier's route of stops,
a rover's sortie (the firmware times each task's work) and its way back to a pick-up stop.

Positions are ENU (the mission frame) converted like :mod:`fleetctl.mavlink.compile`.

Carrier route, per stop k: ``NAV_WAYPOINT`` at the stop (``arrive_seq``), ``NAV_LOITER_UNLIM``
there (``hold_seq``, released with ``set_current(release_seq)``), as in a deployment.

Sortie, launched from a stop::

    NAV_TAKEOFF       above the stop, to the take-off clearance
    per task, worked hovering:
      NAV_WAYPOINT      at the task              -> arrive_seq (the work starts)
      NAV_LOITER_TIME   at the task, param1 = duration s -> done_seq (the work is done)
    per task, worked landed:
      NAV_WAYPOINT      just above the task      -> arrive_seq
      NAV_LAND          at the task
      NAV_DELAY         param1 = duration s      -> done_seq
      NAV_TAKEOFF       to the clearance (when another task follows)
    NAV_LOITER_UNLIM  at the last task when it is worked hovering (waits to be called back)

A rover worked landed last ends its mission on the ground. On an autopilot whose mission ends at
a NAV_LAND (:attr:`Autopilot.landing_ends_mission`: ArduCopter disarms there and restarts its
mission, a NAV_DELAY after it never runs) the sortie's mission ends at the first task worked on the
ground, after its NAV_LAND; that task's ``done_seq`` is -1: the controller times its work and
uploads the rest of the sortie (:func:`sortie_items` with ``takeoff_from``: ``NAV_TAKEOFF`` from
the task, then the tasks left) once it is done. Its way back (:func:`return_items`),
uploaded when it is to leave: ``NAV_TAKEOFF`` (from the ground), ``NAV_WAYPOINT`` above the
pick-up stop (``target_seq``), ``NAV_LOITER_UNLIM`` there (``hold_seq``: it waits for the carrier),
``NAV_LAND`` on the stop (``land_seq``, made current by the controller).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from fleetctl.geo import Origin, local_to_geodetic
from fleetctl.mavlink.autopilots import Autopilot
from fleetctl.mavlink.compile import FRAME, StopItems
from fleetctl.mavlink.link import MissionItem
from fleetctl.mission.flight import MEET_HEIGHT, TAKEOFF_HEIGHT

M = mavlink2
LAND_APPROACH = 0.5  # m above a task worked landed: the flight there ends here, NAV_LAND goes down

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class WorkItems:
    task: str
    arrive_seq: int  # reached: at the task, the work starts
    # reached: the task's duration of work is done (timed by the firmware); -1: the mission ends at
    # the task's landing and the controller times the work (Autopilot.landing_ends_mission)
    done_seq: int


@dataclass(frozen=True)
class SortieItems:
    rover: str
    items: tuple[MissionItem, ...]
    takeoff_seq: int
    work: tuple[WorkItems, ...]


@dataclass(frozen=True)
class ReturnItems:
    items: tuple[MissionItem, ...]
    target_seq: int
    hold_seq: int
    land_seq: int


@dataclass(frozen=True)
class Visit:
    """A task of a sortie as the mission needs it."""

    task: str
    position: Vec3
    duration: float
    ground: bool


class _Writer:
    """Mission items of one vehicle (its autopilot's home item and yaw, its home's height)."""

    def __init__(self, origin: Origin, autopilot: Autopilot | None, home_height: float) -> None:
        self.origin, self.ap, self.hh = origin, autopilot, home_height
        self.items: list[MissionItem] = []

    def add(self, cmd: int, p: Sequence[float], param1: float = 0.0) -> int:
        lat, lon, _alt = local_to_geodetic(p[0], p[1], p[2], self.origin)
        ap = self.ap
        accept = ap.acceptance_radius if ap is not None and cmd == M.MAV_CMD_NAV_WAYPOINT else None
        yaw = 0.0 if cmd == M.MAV_CMD_NAV_LAND else (math.nan if ap is None else ap.unset_param4(cmd))
        self.items.append(MissionItem(cmd, FRAME, param1=param1, param2=float(accept or 0.0), param4=yaw,
                                      x=round(lat * 1e7), y=round(lon * 1e7), z=float(p[2]) - self.hh))
        return len(self.items) - 1

    def delay(self, seconds: float) -> int:
        self.items.append(MissionItem(M.MAV_CMD_NAV_DELAY, M.MAV_FRAME_MISSION, param1=seconds,
                                      param2=-1.0, param3=-1.0, param4=-1.0))
        return len(self.items) - 1

    def home(self, p: Sequence[float]) -> None:
        if self.ap is not None and self.ap.home_is_item0:
            lat, lon, alt = local_to_geodetic(p[0], p[1], self.hh, self.origin)
            self.items.append(MissionItem(M.MAV_CMD_NAV_WAYPOINT, M.MAV_FRAME_GLOBAL,
                                          x=round(lat * 1e7), y=round(lon * 1e7), z=alt))


def route_items(points: Sequence[Vec3], origin: Origin, start: Vec3,
                autopilot: Autopilot | None = None) -> tuple[tuple[MissionItem, ...], tuple[StopItems, ...]]:
    """The carrier's route through ``points`` (ground), holding at each (see the module docstring)."""
    w = _Writer(origin, autopilot, 0.0)
    w.home(start)
    stops: list[StopItems] = []
    for k, p in enumerate(points):
        g = (p[0], p[1], 0.0)
        arrive = w.add(M.MAV_CMD_NAV_WAYPOINT, g)
        hold = w.add(M.MAV_CMD_NAV_LOITER_UNLIM, g)
        stops.append(StopItems(k, arrive, hold, hold + 1 if k + 1 < len(points) else None, ()))
    return tuple(w.items), tuple(stops)


def sortie_items(rover: str, stop: Vec3, visits: Sequence[Visit], origin: Origin,
                 autopilot: Autopilot | None = None, home_height: float = 0.0,
                 takeoff_from: Vec3 | None = None) -> SortieItems:
    """A sortie from ``stop`` through ``visits`` (see the module docstring); ``takeoff_from``: the
    rest of a sortie, from the task on the ground where its last part ended (its position)."""
    w = _Writer(origin, autopilot, home_height)
    if takeoff_from is None:
        w.home(stop)
        takeoff = w.add(M.MAV_CMD_NAV_TAKEOFF, (stop[0], stop[1], TAKEOFF_HEIGHT + home_height))
    else:
        w.home(takeoff_from)
        x, y, z = takeoff_from
        takeoff = w.add(M.MAV_CMD_NAV_TAKEOFF, (x, y, z + TAKEOFF_HEIGHT))
    ends_at_landing = autopilot is not None and autopilot.landing_ends_mission
    work: list[WorkItems] = []
    for i, v in enumerate(visits):
        x, y, z = v.position
        if v.ground:
            arrive = w.add(M.MAV_CMD_NAV_WAYPOINT, (x, y, z + LAND_APPROACH))
            w.add(M.MAV_CMD_NAV_LAND, (x, y, z))
            if ends_at_landing:  # the rest is flown by the next part, once the controller timed the work
                work.append(WorkItems(v.task, arrive, -1))
                break
            done = w.delay(v.duration)
            if i + 1 < len(visits):
                w.add(M.MAV_CMD_NAV_TAKEOFF, (x, y, z + TAKEOFF_HEIGHT))
        else:
            arrive = w.add(M.MAV_CMD_NAV_WAYPOINT, (x, y, z))
            done = w.add(M.MAV_CMD_NAV_LOITER_TIME, (x, y, z), param1=v.duration)
            if i + 1 == len(visits):
                w.add(M.MAV_CMD_NAV_LOITER_UNLIM, (x, y, z))
        work.append(WorkItems(v.task, arrive, done))
    return SortieItems(rover, tuple(w.items), takeoff, tuple(work))


def return_items(here: Vec3, on_ground: bool, stop: Vec3, origin: Origin,
                 autopilot: Autopilot | None = None, home_height: float = 0.0) -> ReturnItems:
    """A rover's way from ``here`` back to ``stop``: above it, waiting, landing on the deck."""
    w = _Writer(origin, autopilot, home_height)
    w.home(here)
    if on_ground:
        w.add(M.MAV_CMD_NAV_TAKEOFF, (here[0], here[1], here[2] + TAKEOFF_HEIGHT))
    above = (stop[0], stop[1], MEET_HEIGHT + home_height)
    target = w.add(M.MAV_CMD_NAV_WAYPOINT, above)
    hold = w.add(M.MAV_CMD_NAV_LOITER_UNLIM, above)
    land = w.add(M.MAV_CMD_NAV_LAND, (stop[0], stop[1], home_height))
    return ReturnItems(tuple(w.items), target, hold, land)


__all__ = ["LAND_APPROACH", "ReturnItems", "SortieItems", "Visit", "WorkItems", "return_items", "route_items",
           "sortie_items"]
