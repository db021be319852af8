"""Plan → MAVLink mission items per vehicle (docs/mavlink.md, "Plan to mission items").

Positions are converted from the plan's ENU frame with :func:`fleetctl.geo.local_to_geodetic` and
written as ``_INT`` coordinates (degrees·1e7) in ``MAV_FRAME_GLOBAL_RELATIVE_ALT_INT``; ``z`` is
the height above home, i.e. the plan's height above the origin altitude minus ``home_height``
(the height of the vehicle's home above the origin altitude: 0 on flat ground, the deck's height
for a rover whose home is on the carrier's deck; :func:`compile_for_fleet` takes each rover's from
its HOME_POSITION). A take-off is to the take-off clearance above home (the deck it sits on).

Carrier route (both plan kinds), for each stop k::

    NAV_WAYPOINT  per intermediate vertex of stop k's carrier_path (no hold)
    NAV_WAYPOINT  at the stop                       -> stops[k].arrive_seq (MISSION_ITEM_REACHED = arrived)
    NAV_LOITER_UNLIM at the stop                    -> stops[k].hold_seq   (holds there indefinitely)

**Hold and release**: a NAV_LOITER_UNLIM never completes, so the carrier waits at the stop
while rovers take off from (or land on) it. The controller releases it with
``vehicle.set_current(stops[k].release_seq)`` (MAV_CMD_DO_SET_MISSION_CURRENT to the item after
the hold, i.e. the first item of the way to the next stop). The last stop has
``release_seq = None``: the carrier stays there until told otherwise.

Deployment rover: ``NAV_TAKEOFF`` (at the stop, to the take-off clearance
``fleetctl.mission.flight.TAKEOFF_HEIGHT``), ``NAV_WAYPOINT`` per vertex of its path after the
start (3D: the straight line from the clearance to the task; the last one is the task →
``target_seq``), ``NAV_LOITER_UNLIM`` at the task (``final_seq``).

Collection rover: ``NAV_TAKEOFF`` to the take-off clearance when its path starts on the ground,
``NAV_WAYPOINT`` per intermediate vertex of its path, ``NAV_WAYPOINT`` to the meeting point above
the carrier's stop at ``max(meet_height, path end height)`` (``target_seq``), ``NAV_LAND`` on the
stop (``final_seq``).

A waypoint's ``param2`` (acceptance radius) is the vehicle's ``Autopilot.acceptance_radius``
(PX4: 1 m; its default NAV_ACC_RAD makes a multicopter's waypoint "reached" 10 m early), else 0
(the firmware's default).

ArduPilot (``home_is_item0``): item 0 is a home placeholder (NAV_WAYPOINT at the vehicle's start,
``MAV_FRAME_GLOBAL``, AMSL); every index above counts it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from fleetctl.geo import Origin, geodetic_to_local, local_to_geodetic
from fleetctl.mavlink.autopilots import Autopilot
from fleetctl.mavlink.link import MissionItem
from fleetctl.mission.flight import GROUND_HEIGHT, MEET_HEIGHT, TAKEOFF_HEIGHT
from planners.core.plan import Plan

if TYPE_CHECKING:
    from fleetctl.mavlink.fleet import Fleet

M = mavlink2
FRAME = M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT


class CompileError(ValueError):
    """A plan that cannot be turned into missions (e.g. no origin)."""


@dataclass(frozen=True)
class StopItems:
    """Where stop ``index`` is in the carrier's mission."""

    index: int
    arrive_seq: int  # NAV_WAYPOINT at the stop: reached = the carrier has arrived
    hold_seq: int  # NAV_LOITER_UNLIM at the stop: the carrier waits here
    release_seq: int | None  # set_current(release_seq) lets it go on; None for the last stop
    rovers: tuple[str, ...]  # rovers launched (deploy) or picked up (collect) at this stop


@dataclass(frozen=True)
class RoverMission:
    rover: str
    stop: int  # index of the carrier stop it departs from (deploy) or lands on (collect)
    items: tuple[MissionItem, ...]
    target_seq: int  # NAV_WAYPOINT at the task (deploy) / above the meeting point (collect)
    final_seq: int  # NAV_LOITER_UNLIM at the task (deploy) / NAV_LAND on the stop (collect)
    task: str | None = None  # deploy only
    home_height: float = 0.0  # its home above the origin altitude (item_position's argument)

    @property
    def takeoff_seq(self) -> int:
        """Index of the NAV_TAKEOFF item (-1 if the mission has none)."""
        return next((i for i, it in enumerate(self.items) if it.command == M.MAV_CMD_NAV_TAKEOFF), -1)

    def positions(self, origin: Origin) -> list[tuple[float, float, float]]:
        """The mission-frame points the rover flies through (the ArduPilot home placeholder left out)."""
        return [item_position(it, origin, self.home_height)
                for it in self.items if it.frame != M.MAV_FRAME_GLOBAL]


@dataclass(frozen=True)
class CompiledPlan:
    """Mission items per vehicle, and where the executor's checkpoints are in them."""

    kind: str  # "deploy" | "collect"
    carrier_id: str
    carrier: tuple[MissionItem, ...]
    stops: tuple[StopItems, ...]
    rovers: dict[str, RoverMission]

    @property
    def missions(self) -> dict[str, list[MissionItem]]:
        """vehicle id -> the item list to upload (carrier first)."""
        out = {self.carrier_id: list(self.carrier)}
        out.update({rid: list(rm.items) for rid, rm in self.rovers.items()})
        return out


AutopilotSpec = Autopilot | Mapping[str, Autopilot] | None


def compile_plan(
    plan: Plan, origin: Origin | None, *, carrier_id: str = "carrier", autopilot: AutopilotSpec = None,
    home_height: float | Mapping[str, float] = 0.0, meet_height: float = MEET_HEIGHT,
    takeoff_height: float = TAKEOFF_HEIGHT,
) -> CompiledPlan:
    """Turn a deployment or collection :class:`~planners.core.plan.Plan` into mission items.

    ``autopilot``: one :class:`~fleetctl.mavlink.autopilots.base.Autopilot` for all vehicles or a mapping
    vehicle id -> autopilot (e.g. ``{vid: v.autopilot for vid, v in fleet.vehicles.items()}``);
    only ``home_is_item0`` matters here. None = no home item (PX4 / generic).
    ``meet_height``: the safe height (above home) of the approach point above a collection stop;
    ``takeoff_height``: the take-off clearance (above home) before a rover turns onto its line;
    ``home_height``: the vehicles' home above the origin altitude, one for all or per vehicle id
    (0 for a vehicle not in the mapping).
    """
    if origin is None:
        raise CompileError("the mission has no origin: mission items need WGS84 coordinates; "
                           "add origin: {lat, lon, alt} to the mission file")
    if plan.kind not in ("deploy", "collect"):
        raise CompileError(f"unknown plan kind {plan.kind!r}")

    def ap_of(vid: str) -> Autopilot | None:
        return autopilot if autopilot is None or isinstance(autopilot, Autopilot) else autopilot.get(vid)

    def home0(vid: str) -> bool:
        ap = ap_of(vid)
        return bool(ap is not None and ap.home_is_item0)

    def hh(vid: str) -> float:
        return float(home_height.get(vid, 0.0) if isinstance(home_height, Mapping) else home_height)

    def wp(cmd: int, p: Sequence[float], vid: str) -> MissionItem:
        lat, lon, _alt = local_to_geodetic(p[0], p[1], p[2], origin)
        ap = ap_of(vid)
        accept = ap.acceptance_radius if ap is not None and cmd == M.MAV_CMD_NAV_WAYPOINT else None
        return MissionItem(cmd, FRAME, param2=float(accept or 0.0), param4=_param4(ap, cmd),
                           x=_e7(lat), y=_e7(lon), z=float(p[2]) - hh(vid))

    def takeoff(p: Sequence[float], vid: str) -> MissionItem:
        return wp(M.MAV_CMD_NAV_TAKEOFF, (p[0], p[1], takeoff_height + hh(vid)), vid)

    def home_item(p: Sequence[float], vid: str) -> MissionItem:
        lat, lon, alt = local_to_geodetic(p[0], p[1], hh(vid), origin)
        return MissionItem(M.MAV_CMD_NAV_WAYPOINT, M.MAV_FRAME_GLOBAL, x=_e7(lat), y=_e7(lon), z=alt)

    # -- carrier -----------------------------------------------------------------------------
    carrier: list[MissionItem] = [home_item(plan.start, carrier_id)] if home0(carrier_id) else []
    stop_items: list[StopItems] = []
    for k, stop in enumerate(plan.stops):
        for v in stop.carrier_path[1:-1]:
            carrier.append(wp(M.MAV_CMD_NAV_WAYPOINT, _ground(v), carrier_id))
        pos = _ground(stop.position)
        carrier.append(wp(M.MAV_CMD_NAV_WAYPOINT, pos, carrier_id))
        carrier.append(wp(M.MAV_CMD_NAV_LOITER_UNLIM, pos, carrier_id))
        hold = len(carrier) - 1
        stop_items.append(StopItems(k, hold - 1, hold, None, tuple(leg.rover for leg in stop.rovers)))
    stop_items = [StopItems(s.index, s.arrive_seq, s.hold_seq,
                            s.hold_seq + 1 if i + 1 < len(stop_items) else None, s.rovers)
                  for i, s in enumerate(stop_items)]

    # -- rovers -------------------------------------------------------------------------------
    rovers: dict[str, RoverMission] = {}
    for k, stop in enumerate(plan.stops):
        for leg in stop.rovers:
            items: list[MissionItem] = []
            if plan.kind == "deploy":
                start = _ground(leg.path[0] if leg.path else stop.position)
                if home0(leg.rover):
                    items.append(home_item(start, leg.rover))
                target = leg.end
                items.append(takeoff(start, leg.rover))
                for v in leg.path[1:]:
                    items.append(wp(M.MAV_CMD_NAV_WAYPOINT, v, leg.rover))
                target_seq = len(items) - 1
                items.append(wp(M.MAV_CMD_NAV_LOITER_UNLIM, target, leg.rover))
            else:
                start = leg.path[0]
                if home0(leg.rover):
                    items.append(home_item(start, leg.rover))
                pos = _ground(stop.position)
                meet_z = max(meet_height, float(leg.end[2]))
                if float(start[2]) <= GROUND_HEIGHT:
                    items.append(takeoff(start, leg.rover))
                for v in leg.path[1:-1]:
                    items.append(wp(M.MAV_CMD_NAV_WAYPOINT, v, leg.rover))
                items.append(wp(M.MAV_CMD_NAV_WAYPOINT, (pos[0], pos[1], meet_z), leg.rover))
                target_seq = len(items) - 1
                items.append(wp(M.MAV_CMD_NAV_LAND, pos, leg.rover))
            rovers[leg.rover] = RoverMission(leg.rover, k, tuple(items), target_seq, len(items) - 1, leg.task,
                                             hh(leg.rover))
    return CompiledPlan(plan.kind, carrier_id, tuple(carrier), tuple(stop_items), rovers)


def with_meeting_hold(rm: RoverMission, autopilot: Autopilot | None) -> tuple[list[MissionItem], int, int]:
    """A collection rover's items with a NAV_LOITER_UNLIM above its meeting point after
    ``target_seq``, so that it waits there until the controller sends it down: (items, the hold's
    index, the landing's index)."""
    items = list(rm.items)
    above = items[rm.target_seq]
    # the waypoint's acceptance radius (param2) is no loiter parameter: PX4 refuses it there
    hold = dataclasses.replace(above, command=M.MAV_CMD_NAV_LOITER_UNLIM, param2=0.0,
                               param4=_param4(autopilot, M.MAV_CMD_NAV_LOITER_UNLIM))
    items.insert(rm.target_seq + 1, hold)
    return items, rm.target_seq + 1, rm.final_seq + 1


HOME_HEIGHT_LIMIT = 20.0  # m: a rover's home further above/below the origin altitude is taken as unknown (0)


def home_heights(fleet: Fleet) -> dict[str, float]:
    """Each rover's home above the origin altitude, from its HOME_POSITION (a rover booted on the
    carrier's deck: the deck's height); rovers without a home, or one more than
    :data:`HOME_HEIGHT_LIMIT` off, are left out (0). The carrier's is not needed: its items are
    on the ground and a ground vehicle ignores their altitude."""
    origin = fleet.carrier.origin
    out: dict[str, float] = {}
    if origin is None:
        return out
    for rid, r in fleet.rovers.items():
        h = r.home_amsl
        if h is not None and abs(h - origin.alt) <= HOME_HEIGHT_LIMIT:
            out[rid] = h - origin.alt
    return out


def compile_for_fleet(plan: Plan, fleet: Fleet, **kw: float) -> CompiledPlan:
    """:func:`compile_plan` with the carrier id, origin, autopilots and rovers' home heights
    (:func:`home_heights`) of a connected fleet."""
    aps = {vid: v.autopilot for vid, v in fleet.vehicles.items() if v.autopilot is not None}
    return compile_plan(plan, fleet.carrier.origin, carrier_id=fleet.carrier_id, autopilot=aps,
                        home_height=home_heights(fleet), **kw)


def is_waypoint(item: MissionItem) -> bool:
    """A NAV_WAYPOINT item: a vertex of a carrier path (or ArduPilot's home placeholder, item 0)."""
    return item.command == M.MAV_CMD_NAV_WAYPOINT


def item_position(item: MissionItem, origin: Origin, home_height: float = 0.0) -> tuple[float, float, float]:
    """The mission-frame (ENU) point of a compiled item: the inverse of the conversion above."""
    if item.frame == M.MAV_FRAME_GLOBAL:
        return geodetic_to_local(item.lat, item.lon, item.z, origin)
    return geodetic_to_local(item.lat, item.lon, origin.alt + item.z + home_height, origin)


def _param4(autopilot: Autopilot | None, command: int) -> float:
    """Yaw left to the vehicle (NaN where its firmware takes it); NAV_LAND keeps 0."""
    if command == M.MAV_CMD_NAV_LAND:
        return 0.0
    return math.nan if autopilot is None else autopilot.unset_param4(command)


def _ground(p: Sequence[float]) -> tuple[float, float, float]:
    return (float(p[0]), float(p[1]), 0.0)


def _e7(deg: float) -> int:
    return int(round(deg * 1e7))


__all__ = ["HOME_HEIGHT_LIMIT", "CompileError", "CompiledPlan", "RoverMission", "StopItems",
           "compile_for_fleet", "compile_plan", "home_heights", "is_waypoint", "item_position",
           "with_meeting_hold"]
