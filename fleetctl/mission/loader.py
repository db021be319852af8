"""Mission files: load and validate the YAML contract of docs/mission-file.md, build the planners' problems.

The schema (every key of every section) is :mod:`fleetctl.mission.schema`, the parsers of single
values :mod:`fleetctl.mission.values`; this module reads the file, applies the schema and the rules
across keys below, and builds the typed :class:`~fleetctl.mission.model.Mission`.

Every error a user can make in a mission file raises :class:`MissionError` whose message names
the file (and line, when the file was read from disk), the key path (``rovers.max_speed``,
``tasks[3].position``; list indices count from 0), what is wrong and what to change.

Decisions beyond the contract:

* ``tasks`` is required. ``tasks: []`` is accepted only with a ``collection`` section (a
  collection-only mission); otherwise an empty task list is an error.
* ``rovers.fleet: {count, sysid_start}`` and ``rovers.units: [{id, sysid, connection}]`` are
  alternatives (at most one). Without either the fleet is ``count`` = number of tasks (or of
  collection rovers for a collection-only mission), ids ``r1..rN``, sysids from carrier sysid + 10.
  A unit without ``connection`` shares the carrier's link.
* ``rovers.deploy_range`` or ``rovers.energy: {initial, task, rho}`` (exactly one); the energy
  form gives d_deploy = rho·(initial − task)/2 (dissertation ch. 3.2). ``endurance_range``
  defaults to rho·initial with energy terms, else to 2·deploy_range (a full battery flies at
  least out and back), and must not be below ``deploy_range``.
* A lat/lon task may omit ``alt`` (then it is on the ground, z = 0); z = alt − origin.alt.
* Collection rover ids must be rovers of the fleet; fault ``vehicle`` must be a vehicle id.
* The carrier's start and every task must lie outside every obstacle and inside ``bounds``.
* Duplicate keys in a YAML mapping are rejected (YAML silently keeps the last one).
* MAVLink system ids are unique per link (:mod:`fleetctl.mission.links`): a vehicle's link is its
  ``connection`` (``sim``: a simulated link of its own), a rover without one shares its carrier's;
  the same sysid on two links is two vehicles, on one link an error naming both key paths.
* ``carriers: [...]`` (docs/teams.md) replaces ``carrier:``: each entry takes the carrier keys (``id``
  and ``sysid`` required) and its own ``fleet`` or ``units``; ``fleet`` ids run on across carriers
  and its ``sysid_start`` defaults to one after the previous carrier's last rover. ``Mission.carrier``
  is the first carrier, ``rovers.units`` every team's rovers, ``Mission.teams`` the decks.
* ``tasks: {file: PATH}`` / ``obstacles: {file: PATH}`` (PATH relative to the mission file's folder)
  read a QGroundControl .plan, GeoJSON, KML or CSV file (:mod:`fleetctl.mission.formats`); the
  result is validated here like a list in the file, and messages name the file and the feature.
  Lat/lon in such a file need the mission's ``origin`` (a .plan's planned home is never taken as
  the origin: it would move every ENU position of the mission; the message quotes it instead).
"""

from __future__ import annotations

import copy
import logging
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

import fleetctl.mission.formats as formats
import fleetctl.mission.limits as L
from fleetctl.geo import Origin, geodetic_to_local
from fleetctl.mission.flight import (
    DEFAULT_ENDURANCE,
    default_land_time,
    default_takeoff_time,
)
from fleetctl.mission.links import link_key, shown_link
from fleetctl.mission.model import (
    CarrierConfig,
    EnergyConfig,
    Fault,
    GeofenceConfig,
    Mission,
    MissionError,
    MqttConfig,
    RoversConfig,
    RoverUnit,
    SimConfig,
    TeamConfig,
    TlsConfig,
    Vec2,
)
from fleetctl.mission.operation import check_one_carrier, check_operation, task_work
from fleetctl.mission.schema import FAULT_PARAM, OBSTACLE_LIST, TASK_LIST, TOP
from fleetctl.mission.values import Ctx, FileRef, KeyPath, fmt_path, point
from fleetctl.mission.yaml_safe import YamlError, read_yaml
from planners.core.problem import (
    CollectRover,
    RoadmapParams,
    Task,
)

if TYPE_CHECKING:
    from shapely.geometry import Point, Polygon

log = logging.getLogger(__name__)


def read_files(ctx: Ctx, d: dict[str, Any], origin: Origin | None, path: Path | None) -> None:
    """Replace ``tasks``/``obstacles`` given as ``{file: PATH}`` by what the file holds, validated
    like a list in the mission; later messages name the file's feature (ctx.notes)."""
    base = path.parent if path is not None else Path.cwd()
    for key in ("tasks", "obstacles"):
        ref = d[key]
        if not isinstance(ref, FileRef):
            continue
        try:
            if key == "tasks":
                tasks = formats.read_tasks(base / ref, origin, shown=str(ref))
                rows: list[Any] = [{"id": t.id, "position": list(t.position)} for t in tasks]
                wheres = [t.where for t in tasks]
            else:
                obstacles = formats.read_obstacles(base / ref, origin, shown=str(ref))
                rows = [[list(v) for v in o.vertices] for o in obstacles]
                wheres = [o.where for o in obstacles]
        except formats.FormatError as exc:
            ctx.fail((key, "file"), str(exc))
        ctx.notes.update({(key, i): f"{ref} {w}" for i, w in enumerate(wheres)})
        d[key] = (TASK_LIST if key == "tasks" else OBSTACLE_LIST)(ctx, rows, (key,))


# --------------------------------------------------------------------------- cross-field rules


def _unique(ctx: Ctx, items: list[tuple[Any, KeyPath]], what: str) -> None:
    seen: dict[Any, KeyPath] = {}
    for value, path in items:
        if value in seen:
            ctx.fail(
                path,
                f"duplicate {what} {value!r} (also at {fmt_path(seen[value])}); make every {what} unique",
            )
        seen[value] = path


def _unique_sysids(ctx: Ctx, rows: list[tuple[str, int, KeyPath]]) -> None:
    """System ids are unique per link (:mod:`fleetctl.mission.links`): ``rows`` are (link key,
    sysid, key path) of every vehicle; a repeat on the same link is an error naming both."""
    seen: dict[tuple[str, int], KeyPath] = {}
    several = len({link for link, _, _ in rows}) > 1
    for link, sysid, path in rows:
        other = seen.get((link, sysid))
        if other is not None:
            on = f" on {shown_link(link)}" if several else ""
            ctx.fail(path, f"duplicate vehicle sysid {sysid}{on} (also at {fmt_path(other)}); make every "
                           "vehicle sysid on one link unique (vehicles on different links may share one)")
        seen[(link, sysid)] = path


def _build_fleet(
    ctx: Ctx, r: dict[str, Any], carrier: dict[str, Any], default_count: int
) -> tuple[RoverUnit, ...]:
    if r["fleet"] is not None and r["units"] is not None:
        ctx.fail(("rovers", "units"), "give either 'fleet: {count, sysid_start}' or 'units: [...]', not both")
    if r["units"] is not None:
        if not r["units"]:
            ctx.fail(("rovers", "units"), "the list of rover units is empty; list one unit per rover")
        units = tuple(RoverUnit(u["id"], u["sysid"], u["connection"]) for u in r["units"])
        for i, u in enumerate(units):
            if u.connection is not None and (u.connection == "sim") != (carrier["connection"] == "sim"):
                ctx.fail(
                    ("rovers", "units", i, "connection"),
                    f"{u.connection!r} mixes a simulated and a real link (carrier connection is "
                    f"{carrier['connection']!r}); remove it to share the carrier's link",
                )
        return units
    fleet = r["fleet"] or {"count": None, "sysid_start": None}
    count = fleet["count"] if fleet["count"] is not None else default_count
    start = fleet["sysid_start"] if fleet["sysid_start"] is not None else carrier["sysid"] + 10
    if start + count - 1 > 255:
        ctx.fail(
            ("rovers", "fleet", "sysid_start"),
            f"rover sysids {start}..{start + count - 1} exceed 255; lower sysid_start (or the carrier sysid)",
        )
    return tuple(RoverUnit(f"r{i + 1}", start + i, None) for i in range(count))


def _polygon(ctx: Ctx, pts: list[Vec2], path: KeyPath) -> Polygon:
    if len(pts) < 3:
        ctx.fail(path, f"an obstacle polygon needs at least 3 vertices [x, y], got {len(pts)}")
    poly = _shape(pts)
    if poly.convex_hull.area <= 0.0 or not poly.is_valid or poly.area <= 0.0:
        flat = poly.convex_hull.area <= 0.0
        reason = "zero area: collinear or repeated vertices" if flat else _why_invalid(poly)
        ctx.fail(
            path,
            f"invalid polygon ({reason}); list the vertices in order around the outline "
            "without self-crossings",
        )
    return poly


def _shape(pts: list[Vec2]) -> Polygon:
    from shapely.geometry import Polygon  # shapely only for missions with polygons: a fast CLI start

    return Polygon(pts)


def _xy_point(x: float, y: float) -> Point:
    from shapely.geometry import Point

    return Point(x, y)


def _why_invalid(poly: Polygon) -> str:
    from shapely.validation import explain_validity

    return str(explain_validity(poly))


def _check_geometry(
    ctx: Ctx, d: dict[str, Any], tasks: tuple[Task, ...]
) -> tuple[tuple[tuple[Vec2, ...], ...], tuple[Vec2, Vec2] | None]:
    bounds = None
    if d["bounds"] is not None:
        b = d["bounds"]
        if len(b) != 2 or not (b[0][0] < b[1][0] and b[0][1] < b[1][1]):
            ctx.fail(
                ("bounds",),
                "expected two corners [[xmin, ymin], [xmax, ymax]] with xmin < xmax and ymin < ymax",
            )
        bounds = (b[0], b[1])
    total = sum(len(pts) for pts in d["obstacles"])
    if total > L.MAX_TOTAL_VERTICES:
        ctx.fail(("obstacles",), f"{total} obstacle vertices in all are too many; give at most "
                                 f"{L.MAX_TOTAL_VERTICES} (merge or simplify the polygons)")
    polys = [_polygon(ctx, pts, ("obstacles", i)) for i, pts in enumerate(d["obstacles"])]
    if polys and bounds is None:
        ctx.fail(
            ("bounds",),
            "obstacles need a workspace for roadmap sampling; add 'bounds: [[xmin, ymin], [xmax, ymax]]'",
        )
    points: list[tuple[str, Vec2, KeyPath]] = _carrier_starts(d)
    points += [(f"task {t.id!r}", t.position[:2], ("tasks", i)) for i, t in enumerate(tasks)]
    for what, (x, y), path in points:
        if bounds is not None and not (
            bounds[0][0] <= x <= bounds[1][0] and bounds[0][1] <= y <= bounds[1][1]
        ):
            ctx.fail(
                path,
                f"{what} at ({x:g}, {y:g}) lies outside bounds {list(bounds[0])}..{list(bounds[1])}; "
                "move it or widen the bounds",
            )
        for j, poly in enumerate(polys):
            if poly.covers(_xy_point(x, y)):
                ctx.fail(
                    path, f"{what} at ({x:g}, {y:g}) lies inside obstacles[{j}]; move it out of the obstacle"
                )
    obstacles = tuple(tuple((float(p[0]), float(p[1])) for p in pts) for pts in d["obstacles"])
    return obstacles, bounds


# --- geofence (docs/field-safety.md): one inclusion polygon, obstacles as exclusion zones -----------
def _geofence(ctx: Ctx, d: dict[str, Any], tasks: tuple[Task, ...], obstacles: tuple[tuple[Vec2, ...], ...],
              bounds: tuple[Vec2, Vec2] | None, origin: Origin | None) -> GeofenceConfig | None:
    g = d["geofence"]
    if g is None:
        return None
    if (g["polygon"] is None) == (g["from"] is None):
        ctx.fail(("geofence", "polygon"), "give exactly one of 'polygon: [[x, y], ...]' or 'from: bounds'")
    if g["from"] is not None:
        if bounds is None:
            ctx.fail(("geofence", "from"),
                     "'from: bounds' needs the mission's 'bounds: [[xmin, ymin], [xmax, ymax]]'")
        (x0, y0), (x1, y1) = bounds
        pts: list[Vec2] = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
    else:
        pts = []
        for i, v in enumerate(g["polygon"]):
            if isinstance(v, dict):
                if origin is None:
                    ctx.fail(("geofence", "polygon", i), "a {lat, lon} vertex needs the mission's 'origin'")
                x, y, _z = geodetic_to_local(v["lat"], v["lon"], origin.alt, origin)
                pts.append((float(x), float(y)))
            else:
                pts.append((float(v[0]), float(v[1])))
        poly = _shape(pts) if len(pts) >= 3 else None
        if poly is None or not poly.is_valid or poly.area <= 0.0:
            why = f"{len(pts)} vertices" if poly is None else _why_invalid(poly)
            ctx.fail(("geofence", "polygon"), f"not a usable polygon ({why}); list at least 3 vertices in "
                     "order around the outline without self-crossings")
    poly = _shape(pts)
    where = ("geofence", "polygon") if g["polygon"] is not None else ("geofence", "from")
    inside = [(what, tuple(p[:2])) for what, p, _ in _carrier_starts(d)]
    inside += [(f"task {t.id!r}", t.position[:2]) for t in tasks]
    for what, (x, y) in inside:
        if not poly.covers(_xy_point(x, y)):
            ctx.fail(where, f"{what} at ({x:g}, {y:g}) lies outside the geofence; "
                     "widen the polygon or move it")
    for t in tasks:
        if g["alt_max"] is not None and t.position[2] > g["alt_max"]:
            ctx.fail(("geofence", "alt_max"), f"task {t.id!r} is {t.position[2]:g} m high, above alt_max "
                     f"{g['alt_max']:g} m; raise alt_max or lower the task")
    return GeofenceConfig(tuple(pts), obstacles, g["alt_max"], g["action"])


def _check_roadmap(
    ctx: Ctx,
    d: dict[str, Any],
    tasks: tuple[Task, ...],
    collection: tuple[CollectRover, ...] | None,
    bounds: tuple[Vec2, Vec2] | None,
    deploy_range: float,
) -> None:
    """Refuse roadmap parameters whose PRM (planner lee-graph, eq. 6.5–6.7) could not be planned in
    bounded time: more than MAX_ROADMAP_NODES nodes or MAX_ROADMAP_EDGES expected edges."""
    names = {str(v) for v in ((d["planner"].deploy, d["planner"].collect)) if v}
    raw_planner = (ctx.raw.get("planner") if isinstance(ctx.raw, dict) else None) or {}
    named = isinstance(raw_planner, dict) and ("deploy" in raw_planner or "collect" in raw_planner)
    if not d["obstacles"] and not (named and "lee-graph" in names) and d["planner"].roadmap is None:
        return  # the open-space planners build no roadmap
    rp = RoadmapParams(**({} if d["planner"].roadmap is None else
                          {k: v for k, v in vars(d["planner"].roadmap).items() if v is not None}))
    radii = [deploy_range] + [c.range for c in collection or ()]
    if bounds is None:  # the graph planners' workspace: the points' box grown by the edge length
        pts = [*(p for _, p, _ in _carrier_starts(d)), *(t.position[:2] for t in tasks)]
        pts += [c.position[:2] for c in collection or ()]
        pad = max(max(radii), 1.0)
        w = max(p[0] for p in pts) - min(p[0] for p in pts) + 2 * pad
        h = max(p[1] for p in pts) - min(p[1] for p in pts) + 2 * pad
    else:
        w, h = bounds[1][0] - bounds[0][0], bounds[1][1] - bounds[0][1]
    side = math.sqrt(w * h)
    where: KeyPath = ("planner", "roadmap") if d["planner"].roadmap is not None else ("bounds",)
    nodes = side * rp.xi1 + rp.xi2
    local = side * rp.xi3 + rp.xi4
    for what, n, key in (("global", nodes, "xi1"), ("local", local, "xi3")):
        if n > L.MAX_ROADMAP_NODES:
            ctx.fail(
                where,
                f"the {what} roadmap would have {n:.0f} nodes (√(w·h) = {side:.0f} m); at most "
                f"{L.MAX_ROADMAP_NODES} can be planned: lower planner.roadmap.{key} (or its constant term) "
                "or the workspace bounds",
            )
    delta = max(max(radii), (w + h) / 2.0 * rp.phi)
    edges = nodes * nodes / 2.0 * min(1.0, math.pi * delta * delta / (w * h))
    if edges > L.MAX_ROADMAP_EDGES:
        ctx.fail(
            where,
            f"the roadmap would have about {edges:.0f} edges ({nodes:.0f} nodes, edges up to {delta:.0f} m); "
            f"at most {L.MAX_ROADMAP_EDGES} can be planned: lower planner.roadmap.xi1/xi2, phi "
            "or rovers.deploy_range",
        )


def _build(ctx: Ctx, data: Any, path: Path | None) -> Mission:
    if data is None:
        ctx.fail((), "the mission file is empty; see the annotated examples in missions/ for the keys")
    ctx.raw = data
    d = ctx.section(data, (), TOP)
    origin: Origin | None = d["origin"]
    _carriers(ctx, d)
    check_one_carrier(ctx.fail, d)
    read_files(ctx, d, origin, path)
    carrier, r = d["carrier"], d["rovers"]
    tasks, collection = _tasks_and_collection(ctx, d, origin)
    deploy_range, endurance, energy = _ranges(ctx, r)
    _check_task_heights(ctx, tasks, deploy_range)
    teams: tuple[tuple[dict[str, Any], tuple[str, ...]], ...]
    if d["carriers"] is None:
        units = _fleet_units(ctx, r, carrier, tasks, collection, d["operation"])
        teams = ((carrier, tuple(u.id for u in units)),)
    else:
        units, teams = _team_units(ctx, d, tasks, collection)
    work = task_work(d["tasks"], d["dwell"], r["work"])
    check_operation(ctx.fail, d, tasks, work, endurance)
    obstacles, bounds = _check_geometry(ctx, d, tasks)
    geofence = _geofence(ctx, d, tasks, obstacles, bounds, origin)
    _check_roadmap(ctx, d, tasks, collection, bounds, deploy_range)
    faults = _faults(ctx, d, {u.id for u in units} | {c["id"] for c, _ in teams})
    mission = Mission(
        name=d["name"] or (path.stem if path is not None else "mission"),
        origin=origin,
        carrier=_carrier_config(carrier),
        rovers=RoversConfig(r["max_speed"], r["accel"], deploy_range, endurance, r["reserve"], units, energy,
                            **_flight_times(r, carrier["deck_height"]),
                            firmware_speeds=_firmware_speeds(r, carrier["connection"]),
                            handling_given=(r["takeoff_time"] is not None, r["land_time"] is not None),
                            work=r["work"]),
        tasks=tasks,
        obstacles=obstacles,
        bounds=bounds,
        collection=collection,
        sim=SimConfig(d["sim"]["speedup"], tuple(faults)),
        links=d["links"],
        planner=d["planner"],
        dwell=d["dwell"],
        mqtt=_mqtt(ctx, d, path),
        raw=copy.deepcopy(data),
        path=path,
        geofence=geofence,
        teams=tuple(TeamConfig(_carrier_config(c), ids) for c, ids in teams),
        work=tuple((t.id, w) for t, w in zip(tasks, work, strict=True)),
        operation=d["operation"],
    )
    log.debug(
        "mission %s: %d tasks, %d rovers, d_deploy %.2f m", mission.name, len(tasks), len(units), deploy_range
    )
    return mission


def _tasks_and_collection(
    ctx: Ctx, d: dict[str, Any], origin: Origin | None
) -> tuple[tuple[Task, ...], tuple[CollectRover, ...] | None]:
    tasks = tuple(Task(t["id"], point(ctx, t, ("tasks", i), origin)) for i, t in enumerate(d["tasks"]))
    collection = None
    if d["collection"] is not None:
        rows = d["collection"]["rovers"]
        if not rows:
            ctx.fail(
                ("collection", "rovers"),
                "the list is empty; list the rovers to collect {id, position, range}",
            )
        collection = tuple(
            CollectRover(c["id"], point(ctx, c, ("collection", "rovers", i), origin), c["range"])
            for i, c in enumerate(rows)
        )
    if not tasks and collection is None:
        ctx.fail(
            ("tasks",),
            "the task list is empty; add at least one task {id, position} "
            "(an empty list is allowed only in a collection-only mission with a 'collection' section)",
        )
    _unique(ctx, [(t.id, ("tasks", i, "id")) for i, t in enumerate(tasks)], "task id")
    return tasks, collection


def _flight_times(r: dict[str, Any], deck_height: float) -> dict[str, float]:
    """Climb and landing speeds (default: the cruise speed) and the time model's take-off (a climb at
    the rovers' acceleration) and touch-down times (default: fleetctl.mission.flight; the descent
    onto a deck ``deck_height`` up)."""
    climb = r["climb_rate"] if r["climb_rate"] is not None else r["max_speed"]
    land = r["land_speed"] if r["land_speed"] is not None else climb
    takeoff = r["takeoff_time"] if r["takeoff_time"] is not None else default_takeoff_time(climb, r["accel"])
    touch = r["land_time"] if r["land_time"] is not None else default_land_time(land, deck_height)
    return {"climb_rate": climb, "land_speed": land, "takeoff_time": takeoff, "land_time": touch}


def _ranges(ctx: Ctx, r: dict[str, Any]) -> tuple[float, float, EnergyConfig | None]:
    """d_deploy (given, or from energy terms: dissertation ch. 3.2), endurance_range, energy."""
    if (r["deploy_range"] is None) == (r["energy"] is None):
        ctx.fail(
            ("rovers", "deploy_range"),
            "give exactly one of 'deploy_range' (metres) or "
            "'energy: {initial, task, rho}' (d_deploy = rho·(initial − task)/2)",
        )
    energy = None
    if r["energy"] is not None:
        energy = EnergyConfig(**r["energy"])
        if energy.task >= energy.initial:
            ctx.fail(
                ("rovers", "energy", "task"),
                f"the task energy {energy.task:g} leaves nothing of the initial "
                f"energy {energy.initial:g} for flight; lower 'task' or raise 'initial'",
            )
        deploy_range = energy.rho * (energy.initial - energy.task) / 2.0
        if not L.MIN_RANGE <= deploy_range <= L.MAX_RANGE:
            ctx.fail(
                ("rovers", "energy"),
                f"the deploy range rho·(initial − task)/2 = {deploy_range:g} m is outside "
                f"{L.MIN_RANGE:g}..{L.MAX_RANGE:g} m; change rho, initial or task",
            )
    else:
        deploy_range = r["deploy_range"]
    endurance = r["endurance_range"]
    if endurance is None:
        # a multirotor burns its battery per second in the air, hovering included: without energy
        # terms, a DEFAULT_ENDURANCE battery at cruise speed (at least there and back)
        endurance = (energy.rho * energy.initial if energy is not None
                     else max(2.0 * deploy_range, DEFAULT_ENDURANCE * r["max_speed"]))
        endurance = min(endurance, max(L.MAX_RANGE, deploy_range))  # physical cap of a derived value
    elif endurance < deploy_range:
        ctx.fail(
            ("rovers", "endurance_range"),
            f"{endurance:g} m on a full battery is less than the deploy range "
            f"{deploy_range:g} m; raise endurance_range or lower deploy_range",
        )
    return deploy_range, endurance, energy


def _check_task_heights(ctx: Ctx, tasks: tuple[Task, ...], deploy_range: float) -> None:
    for i, t in enumerate(tasks):
        z = t.position[2]
        if z < 0:
            ctx.fail(
                ("tasks", i),
                f"task {t.id!r} has a negative height z = {z:g} m; heights are above ground (>= 0)",
            )
        if z > deploy_range:
            ctx.fail(
                ("tasks", i),
                f"task {t.id!r} is {z:g} m high, higher than rovers.deploy_range "
                f"{deploy_range:g} m, so no rover can reach it; lower the task or raise the deploy range",
            )


def _fleet_units(
    ctx: Ctx, r: dict[str, Any], carrier: dict[str, Any], tasks: tuple[Task, ...],
    collection: tuple[CollectRover, ...] | None, operation: bool = False,
) -> tuple[RoverUnit, ...]:
    """The rover units, enough for the tasks (unless the mission is a long operation, whose rovers
    serve several tasks each), ids unique, sysids unique per link, collection rovers among them."""
    n_default = len(tasks) if tasks else len(collection or ())
    units = _build_fleet(ctx, r, carrier, n_default)
    fleet_key = ("rovers", "units") if r["units"] is not None else ("rovers", "fleet", "count")
    if len(units) < len(tasks) and not operation:
        ctx.fail(
            fleet_key,
            f"only {len(units)} rover(s) for {len(tasks)} tasks; every task needs its own rover, "
            f"give at least {len(tasks)} rovers (or plan a long operation, where rovers serve several "
            "tasks each: 'operation: true', docs/mission-file.md)",
        )

    def unit_path(i: int, key: str) -> KeyPath:
        if r["units"] is not None:
            return ("rovers", "units", i, key)
        return ("rovers", "fleet", "sysid_start") if key == "sysid" else ("rovers", "fleet")

    _unique(
        ctx,
        [(carrier["id"], ("carrier", "id"))] + [(u.id, unit_path(i, "id")) for i, u in enumerate(units)],
        "vehicle id",
    )
    home = link_key(carrier["connection"], carrier["id"])
    _unique_sysids(ctx, [(home, carrier["sysid"], ("carrier", "sysid"))]
                   + [(link_key(u.connection, u.id, home), u.sysid, unit_path(i, "sysid"))
                      for i, u in enumerate(units)])
    _check_collection(ctx, collection, {u.id for u in units})
    return tuple(units)


def _check_collection(ctx: Ctx, collection: tuple[CollectRover, ...] | None, rover_ids: set[str]) -> None:
    """Collection rover ids: unique, and rovers of the fleet."""
    if collection is not None:
        _unique(
            ctx,
            [(c.id, ("collection", "rovers", i, "id")) for i, c in enumerate(collection)],
            "collection rover id",
        )
        for i, c in enumerate(collection):
            if c.id not in rover_ids:
                ctx.fail(
                    ("collection", "rovers", i, "id"),
                    f"{c.id!r} is not a rover of the fleet "
                    f"({', '.join(sorted(rover_ids))}); use a fleet rover id",
                )


# --- several carriers (docs/teams.md): carriers: [{carrier keys..., fleet | units}] ------------------
def _carrier_config(c: dict[str, Any]) -> CarrierConfig:
    keys = {k: v for k, v in c.items() if k not in ("fleet", "units")}
    keys["firmware_speeds"] = _firmware_speeds(c, c["connection"])
    return CarrierConfig(**{**keys, "position": tuple(c["position"])})


def _firmware_speeds(section: dict[str, Any], connection: str) -> str:
    """``firmware_speeds``: as given, else ``set`` on real links and ``keep`` on the simulated
    fleet (which flies the mission's speeds already)."""
    given = section.get("firmware_speeds")
    return str(given) if given is not None else ("keep" if connection == "sim" else "set")


def _carrier_starts(d: dict[str, Any]) -> list[tuple[str, Vec2, KeyPath]]:
    """Every carrier's start: what to call it in a message, where it is, its key path."""
    if d.get("carriers") is None:
        return [("the carrier's start", d["carrier"]["position"], ("carrier", "position"))]
    return [(f"carrier {c['id']!r}'s start", c["position"], ("carriers", i, "position"))
            for i, c in enumerate(d["carriers"])]


def _carriers(ctx: Ctx, d: dict[str, Any]) -> None:
    """Exactly one of ``carrier:`` and ``carriers:``; with ``carriers:`` the rovers are the carriers'
    own and ``d["carrier"]`` becomes the first carrier (the one that flies a one-team mission)."""
    teams = d["carriers"]
    if d["carrier"] is not None and teams is not None:
        ctx.fail(("carriers",), "give either 'carrier: {...}' (one team) or 'carriers: [...]', not both")
    if teams is None:
        if d["carrier"] is None:
            ctx.fail(("carrier",), "required key is missing; add 'carrier: {id, position, max_speed, ...}' "
                                   "(one team) or 'carriers: [...]' (several)")
        return
    if not teams:
        ctx.fail(("carriers",), "the list is empty; list one carrier {id, sysid, position, ..., fleet} "
                                "per team")
    for key in ("fleet", "units"):
        if d["rovers"][key] is not None:
            ctx.fail(("rovers", key), f"with 'carriers:' every carrier lists its own rovers; move "
                                      f"rovers.{key} into each carriers[i].{key}")
    for i, c in enumerate(teams[1:], 1):
        if (c["connection"] == "sim") != (teams[0]["connection"] == "sim"):
            ctx.fail(("carriers", i, "connection"), f"{c['connection']!r} mixes a simulated and a real "
                     f"fleet (carriers[0].connection is {teams[0]['connection']!r}); use one kind for every "
                     "carrier")
    d["carrier"] = teams[0]


def _team_units(
    ctx: Ctx, d: dict[str, Any], tasks: tuple[Task, ...], collection: tuple[CollectRover, ...] | None,
) -> tuple[tuple[RoverUnit, ...], tuple[tuple[dict[str, Any], tuple[str, ...]], ...]]:
    """Every carrier's rovers (``fleet:`` ids run on across carriers in list order), enough for the
    tasks, ids unique over every vehicle, sysids unique per link, collection rovers among them."""
    rows: list[tuple[RoverUnit, KeyPath, KeyPath]] = []
    teams = []
    links: dict[str, str] = {}  # vehicle id -> its link
    for i, c in enumerate(d["carriers"]):
        next_sysid = rows[-1][0].sysid + 1 if rows else c["sysid"] + 10
        home = link_key(c["connection"], c["id"])
        own = _team_fleet(ctx, c, ("carriers", i), len(rows), next_sysid, home not in links.values())
        rows += own
        teams.append((c, tuple(u.id for u, _, _ in own)))
        links[c["id"]] = home
        links.update({u.id: link_key(u.connection, u.id, home) for u, _, _ in own})
    if len(rows) < len(tasks):
        ctx.fail(("carriers",), f"only {len(rows)} rover(s) on the carriers for {len(tasks)} tasks; every "
                                f"task needs its own rover, give at least {len(tasks)} rovers in all")
    cars = d["carriers"]
    _unique(ctx, [(c["id"], ("carriers", i, "id")) for i, c in enumerate(cars)]
            + [(u.id, p) for u, p, _ in rows], "vehicle id")
    _unique_sysids(ctx, [(links[c["id"]], c["sysid"], ("carriers", i, "sysid")) for i, c in enumerate(cars)]
                   + [(links[u.id], u.sysid, p) for u, _, p in rows])
    _check_collection(ctx, collection, {u.id for u, _, _ in rows})
    return tuple(u for u, _, _ in rows), tuple(teams)


def _team_fleet(ctx: Ctx, c: dict[str, Any], path: KeyPath, first: int, next_sysid: int,
                own_link: bool = False) -> list[tuple[RoverUnit, KeyPath, KeyPath]]:
    """One carrier's rovers with the key paths of their id and sysid: ``units: [...]`` as given, or
    ``fleet: {count, sysid_start}`` as r<first+1>.. with sysids from sysid_start (default: after
    the previous carrier's last rover; for the first carrier, its sysid + 10)."""
    if c["fleet"] is not None and c["units"] is not None:
        ctx.fail(path + ("units",), "give either 'fleet: {count, sysid_start}' or 'units: [...]', not both")
    if c["units"] is not None:
        if not c["units"]:
            ctx.fail(path + ("units",), "the list of rover units is empty; list one unit per rover")
        out = []
        for j, u in enumerate(c["units"]):
            up = path + ("units", j)
            if u["connection"] is not None and (u["connection"] == "sim") != (c["connection"] == "sim"):
                ctx.fail(up + ("connection",), f"{u['connection']!r} mixes a simulated and a real link "
                         f"(carrier connection is {c['connection']!r}); remove it to share the carrier's "
                         "link")
            out.append((RoverUnit(u["id"], u["sysid"], u["connection"]), up + ("id",), up + ("sysid",)))
        return out
    if c["fleet"] is None or c["fleet"]["count"] is None:
        ctx.fail(path + ("fleet",) + (() if c["fleet"] is None else ("count",)),
                 "required key is missing; every carrier of 'carriers:' needs its own rovers: "
                 "'fleet: {count, sysid_start}' or 'units: [{id, sysid}, ...]'")
    count, start = c["fleet"]["count"], c["fleet"]["sysid_start"] or next_sysid
    fp = path + ("fleet",)
    if start + count - 1 > 255:
        fresh = c["sysid"] + 1 if c["sysid"] + count <= 255 else 1 if count < c["sysid"] else None
        hint = (f"; this carrier's link is its own (system ids are unique per link): 'sysid_start: {fresh}' "
                "numbers its rovers afresh" if own_link and fresh is not None else "")
        ctx.fail(fp + ("sysid_start",), f"rover sysids {start}..{start + count - 1} exceed 255; lower "
                                        f"sysid_start (or the carriers' sysids){hint}")
    return [(RoverUnit(f"r{first + j + 1}", start + j, None), fp, fp + ("sysid_start",))
            for j in range(count)]


def _faults(ctx: Ctx, d: dict[str, Any], vehicles: set[str]) -> list[Fault]:
    faults = []
    for i, f in enumerate(d["sim"]["faults"]):
        fp: KeyPath = ("sim", "faults", i)
        if f["vehicle"] is not None and f["vehicle"] not in vehicles:
            ctx.fail(
                fp + ("vehicle",),
                f"{f['vehicle']!r} is not a vehicle of this mission "
                f"({', '.join(sorted(vehicles))}); omit 'vehicle' to affect every vehicle",
            )
        needed = FAULT_PARAM.get(f["kind"])
        for param in FAULT_PARAM.values():
            if param != needed and f[param] is not None:
                ctx.fail(fp + (param,), f"'{param}' does not apply to kind {f['kind']}; remove it")
        if needed is not None and f[needed] is None:
            ctx.fail(fp + (needed,), f"required key is missing; kind {f['kind']} needs '{needed}:'")
        if f["until"] is not None and f["until"] <= f["at"]:
            ctx.fail(fp + ("until",), f"until ({f['until']:g} s) must be later than at ({f['at']:g} s)")
        faults.append(Fault(**f))
    return faults


def _mqtt(ctx: Ctx, d: dict[str, Any], path: Path | None) -> MqttConfig | None:
    if d["mqtt"] is None:
        return None
    m = dict(d["mqtt"])
    tls: TlsConfig | None = m["tls"]
    if tls is not None and (tls.cert is None) != (tls.key is None):
        ctx.fail(
            ("mqtt", "tls", "cert" if tls.cert is None else "key"),
            "a client certificate needs both 'cert' and 'key'; add the missing one",
        )
    name_for_topic = d["name"] or (path.stem if path else "mission")
    m["topic_prefix"] = m["topic_prefix"] or f"fleetctl/{name_for_topic}"
    return MqttConfig(**m)


# --------------------------------------------------------------------------- YAML with line numbers
# (bounded: fleetctl.mission.yaml_safe; the line map visits every node once, never alias copies)


def parse_mission(data: dict[str, Any], source: str) -> Mission:
    """Validate an already parsed mission mapping; ``source`` names it in error messages."""
    return _build(Ctx(source), data, None)


def load_mission(path: str | Path) -> Mission:
    """Read, parse and validate a mission YAML file. Raises :class:`MissionError` on any problem
    (never another exception for any file content: see :mod:`fleetctl.mission.limits`)."""
    path = Path(path)
    source = str(path)
    try:
        with path.open("rb") as f:
            raw = f.read(L.MAX_FILE_BYTES + 1)
        if len(raw) > L.MAX_FILE_BYTES:
            raise MissionError(f"{source}: the mission file is larger than {L.MAX_FILE_BYTES} bytes; "
                               "a mission file is a few kilobytes: remove what does not belong in it")
        text = raw.decode("utf-8")
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise MissionError(f"{source}: cannot read the mission file: {exc}") from None
    return parse_mission_text(text, source, path)


def parse_mission_text(text: str, source: str, path: Path | None = None) -> Mission:
    """Parse and validate mission YAML ``text`` (``source`` names it in messages)."""
    ctx = Ctx(source)
    try:
        data, lines = read_yaml(text)
    except YamlError as exc:
        line = f":{exc.line}" if exc.line is not None else ""
        raise MissionError(f"{source}{line}: {exc.message}") from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = f":{mark.line + 1}" if mark is not None else ""
        what = str(exc.problem or exc.context or "syntax error")
        if exc.context and exc.problem:
            started = exc.context_mark
            at = f" started at line {started.line + 1}" if started is not None else ""
            what += f" ({exc.context}{at})"
        raise MissionError(f"{source}{line}: malformed YAML: {what}; fix the syntax there") from None
    except yaml.YAMLError as exc:
        raise MissionError(f"{source}: malformed YAML: {exc}") from None
    ctx.lines = lines
    return _build(ctx, data, path)
