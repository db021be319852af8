"""A plan for other tools: one QGroundControl ``.plan`` per vehicle and a ``plan.geojson``.

``fleetctl plan --export DIR`` and every run folder (``RUN/export/``) use :func:`export_plan`. The
``.plan`` files hold the mission items the controller uploads - the same
:class:`~fleetctl.mavlink.compile.CompiledPlan` - so QGroundControl shows (and could fly) exactly
that mission: items in upload order (``doJumpId`` = sequence number + 1), MAVLink's ``_INT``
frames written as their float twins (as QGroundControl does), NaN parameters as ``null``, the
obstacles as exclusion polygons and the mission's geofence as the inclusion polygon.
ArduPilot's home placeholder (item 0, the only item the compiler writes in ``MAV_FRAME_GLOBAL``)
becomes ``plannedHomePosition``, as QGroundControl keeps it; otherwise the planned home is the
vehicle's start at the origin's altitude (the home the compiled relative altitudes refer to).

``plan.geojson`` (RFC 7946, [lon, lat, alt] with alt = origin.alt + z) is a FeatureCollection of
the tasks, the obstacles, the carrier's stops and route, and every rover flight with its times.
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fleetctl.geo import Origin, local_to_geodetic
from fleetctl.mission.formats import geojson_file as gj
from fleetctl.mission.formats import qgc_plan
from fleetctl.mission.formats.common import Vec2, Vec3

if TYPE_CHECKING:
    from fleetctl.mavlink.autopilots import Autopilot
    from fleetctl.mavlink.compile import CompiledPlan
    from fleetctl.mavlink.link import MissionItem
    from fleetctl.mission.model import Mission
    from planners.core.plan import Plan

MAV_TYPE_QUADROTOR = 2  # the rovers (small UAVs) when no HEARTBEAT told otherwise
MAV_TYPE_GROUND_ROVER = 10  # the carrier, as the simulated fleet's
MAV_FRAME_GLOBAL = 0
GEOJSON_NAME = "plan.geojson"
_SAFE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")


def export_plan(mission: Mission, plan: Plan, compiled: CompiledPlan, out_dir: str | Path, *,
                autopilots: Mapping[str, Autopilot] | None = None, prune: bool = False) -> list[Path]:
    """Write ``<vehicle>.plan`` for every vehicle of ``compiled`` and ``plan.geojson`` into
    ``out_dir`` (created). Returns the files written, carrier first. ``prune``: also remove the
    ``.plan`` files of vehicles not in this plan (a run folder's export after a replan)."""
    origin = mission.origin
    if origin is None:
        raise ValueError("exporting needs the mission's origin: add origin: {lat, lon, alt}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    starts = {leg.rover: leg.start for leg in plan.legs()} | {mission.carrier.id: plan.start}
    for vid, items in compiled.missions.items():
        doc = vehicle_plan(mission, vid, items, (autopilots or {}).get(vid), start=starts.get(vid))
        written.append(_write(out / f"{file_name(vid)}.plan", doc))
    written.append(_write(out / GEOJSON_NAME, plan_geojson(mission, plan)))
    if prune:
        for stale in set(out.glob("*.plan")) - set(written):
            stale.unlink()
    return written


def file_name(vehicle: str) -> str:
    """A vehicle id as a file name (ids with other characters get them replaced by '_')."""
    return vehicle if _SAFE_NAME.fullmatch(vehicle) else re.sub(r"[^A-Za-z0-9_.-]", "_", vehicle).lstrip(".")


def _write(path: Path, doc: dict[str, Any]) -> Path:
    path.write_text(json.dumps(doc, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    return path


def _latlon(p: Sequence[float], origin: Origin) -> Vec3:
    return local_to_geodetic(float(p[0]), float(p[1]), float(p[2]) if len(p) > 2 else 0.0, origin)


def _fence(mission: Mission, origin: Origin) -> tuple[list[list[Vec2]], list[Vec2] | None]:
    def ring(poly: Sequence[Vec2]) -> list[Vec2]:
        return [_latlon((x, y), origin)[:2] for x, y in poly]

    inclusion = ring(mission.geofence.polygon) if mission.geofence is not None else None
    return [ring(p) for p in mission.obstacles], inclusion


def vehicle_plan(mission: Mission, vid: str, items: Sequence[MissionItem], autopilot: Autopilot | None = None,
                 start: Sequence[float] | None = None) -> dict[str, Any]:
    """The ``.plan`` document of one vehicle's compiled mission; ``start``: where its flight (or
    route) starts in ENU metres, the planned home (at the origin's altitude) unless item 0 is
    ArduPilot's home placeholder."""
    origin = mission.origin
    assert origin is not None
    items = list(items)
    carrier = vid == mission.carrier.id
    if items and items[0].frame == MAV_FRAME_GLOBAL and items[0].command == qgc_plan.NAV_WAYPOINT:
        home = (items[0].lat, items[0].lon, float(items[0].z))  # ArduPilot's home placeholder
        items = items[1:]
    elif start is not None:
        home = _latlon((start[0], start[1], 0.0), origin)
    elif carrier or not items:
        home = _latlon(mission.carrier.position, origin)
    else:
        home = (items[0].lat, items[0].lon, origin.alt)
    mav_type = autopilot.mav_type if autopilot is not None and autopilot.mav_type else (
        MAV_TYPE_GROUND_ROVER if carrier else MAV_TYPE_QUADROTOR)
    speed = mission.carrier.max_speed if carrier else mission.rovers.max_speed
    exclusions, inclusion = _fence(mission, origin)
    return qgc_plan.plan_document(
        items, home=home, firmware_type=qgc_plan.MAV_AUTOPILOT.get(autopilot.name if autopilot else "", 0),
        vehicle_type=mav_type, cruise_speed=speed, hover_speed=speed, exclusions=exclusions,
        inclusion=inclusion,
    )


# --------------------------------------------------------------------------- plan.geojson


def plan_geojson(mission: Mission, plan: Plan) -> dict[str, Any]:
    """The plan as a GeoJSON FeatureCollection (tasks, obstacles, stops, routes, rover flights)."""
    origin = mission.origin
    assert origin is not None
    feats = [gj.feature(gj.point(*_latlon(t.position, origin)), kind="task", id=t.id, height=t.position[2])
             for t in mission.tasks]
    feats += [gj.feature(gj.polygon([_latlon((x, y), origin)[:2] for x, y in poly]), kind="obstacle", index=i)
              for i, poly in enumerate(mission.obstacles)]
    feats += _carrier_features(mission, plan, origin)
    feats += _rover_features(plan, origin)
    about = {"schema": "fleetctl.plan/1", "mission": mission.name, "kind": plan.kind, "planner": plan.planner,
             "makespan": plan.makespan, "carrier_distance": plan.carrier_distance}
    return gj.collection(feats, fleetctl=about)


def _carrier_features(mission: Mission, plan: Plan, origin: Origin) -> list[dict[str, Any]]:
    route: list[Vec3] = [_latlon(plan.start, origin)]
    feats = []
    prev = plan.start
    for k, stop in enumerate(plan.stops):
        path = stop.carrier_path or [prev, stop.position]
        route += [_latlon((p[0], p[1], 0.0), origin) for p in path[1:]]
        prev = stop.position
        feats.append(gj.feature(gj.point(*_latlon((stop.position[0], stop.position[1], 0.0), origin)),
                                kind="stop", vehicle=mission.carrier.id, index=k, arrive=stop.arrive,
                                depart=stop.depart, rovers=[leg.rover for leg in stop.rovers]))
    feats.insert(0, gj.feature(gj.line(route), kind="carrier_route", vehicle=mission.carrier.id, depart=0.0,
                               arrive=plan.stops[-1].arrive if plan.stops else 0.0,
                               distance=plan.carrier_distance))
    return feats


def _rover_features(plan: Plan, origin: Origin) -> list[dict[str, Any]]:
    feats = []
    for k, stop in enumerate(plan.stops):
        for leg in stop.rovers:
            path = leg.path if len(leg.path) >= 2 else [stop.position, leg.end]
            depart = stop.depart if plan.kind == "deploy" else 0.0
            feats.append(gj.feature(gj.line([_latlon(p, origin) for p in path]), kind="rover_flight",
                                    rover=leg.rover, task=leg.task, stop=k, depart=depart, arrive=leg.arrive))
    return feats


__all__ = ["GEOJSON_NAME", "export_plan", "file_name", "plan_geojson", "vehicle_plan"]
