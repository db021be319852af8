"""Mission files: load and validate the YAML contract of DESIGN.md, build the planners' problems.

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
"""

from __future__ import annotations

import copy
import difflib
import logging
import math
import re
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, NoReturn

import yaml
from shapely.geometry import Point, Polygon
from shapely.validation import explain_validity

from fleetctl.geo import Origin, geodetic_to_local
from fleetctl.mission.model import (
    FAILSAFE_ACTIONS,
    FAULT_KINDS,
    FENCE_ACTIONS,
    CarrierConfig,
    EnergyConfig,
    Fault,
    GeofenceConfig,
    LinksConfig,
    Mission,
    MissionError,
    MqttConfig,
    PlannerConfig,
    RoadmapConfig,
    RoversConfig,
    RoverUnit,
    SigningConfig,
    SimConfig,
    TlsConfig,
)
from planners.problem import (
    CollectRover,
    Task,
)

log = logging.getLogger(__name__)

from fleetctl.mission.model import Vec2, Vec3  # noqa: E402

KeyPath = tuple[str | int, ...]

# --------------------------------------------------------------------------- schema helper

_REQUIRED = object()
Parser = Callable[["_Ctx", Any, KeyPath], Any]


def _fmt_path(path: KeyPath) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "(top level)"


def _type_name(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"a boolean ({str(value).lower()})"
    if isinstance(value, int | float):
        return f"a number ({value})"
    if isinstance(value, str):
        return f"a string ({value!r})"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, dict):
        return "a mapping"
    return type(value).__name__


class _Ctx:
    def __init__(self, source: str, lines: Mapping[KeyPath, int] | None = None) -> None:
        self.source = source
        self.lines = lines or {}

    def fail(self, path: KeyPath, message: str) -> NoReturn:
        where = self.source
        for n in range(len(path), -1, -1):  # the line of the key, or of its nearest parent
            if path[:n] in self.lines:
                where = f"{self.source}:{self.lines[path[:n]]}"
                break
        raise MissionError(f"{where}: {_fmt_path(path)}: {message}")

    def section(self, value: Any, path: KeyPath, spec: Mapping[str, tuple[Parser, Any]]) -> dict[str, Any]:
        """Check a mapping against ``spec`` (key → (parser, default or _REQUIRED)); parse every key."""
        if not isinstance(value, dict):
            self.fail(path, f"expected a mapping with keys {', '.join(spec)}, got {_type_name(value)}")
        for key in value:
            if key not in spec:
                close = difflib.get_close_matches(str(key), list(spec), n=1)
                hint = f"did you mean '{close[0]}'? " if close else ""
                self.fail(path + (str(key),), f"unknown key; {hint}allowed keys here: {', '.join(spec)}")
        out: dict[str, Any] = {}
        for key, (parse, default) in spec.items():
            if key in value:
                out[key] = parse(self, value[key], path + (key,))
            elif default is _REQUIRED:
                self.fail(path + (key,), f"required key is missing; add '{key}:' to {_fmt_path(path)}")
            else:
                out[key] = default
        return out


def _number(
    *,
    gt: float | None = None,
    ge: float | None = None,
    lt: float | None = None,
    le: float | None = None,
    null: bool = False,
    unit: str = "",
) -> Parser:
    """A real number (bool is not a number) within the given limits; ``null`` allows None."""
    limits = [f"{op} {x:g}" for op, x in ((">", gt), (">=", ge), ("<", lt), ("<=", le)) if x is not None]
    want = " ".join(["a number", *limits]) + (f" ({unit})" if unit else "") + (" or null" if null else "")

    def parse(ctx: _Ctx, v: Any, path: KeyPath) -> float | None:
        if v is None and null:
            return None
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            ctx.fail(path, f"expected {want}, got {_type_name(v)}")
        bad = (
            (gt is not None and not v > gt)
            or (ge is not None and not v >= ge)
            or (lt is not None and not v < lt)
            or (le is not None and not v <= le)
        )
        if bad:
            ctx.fail(path, f"{v} is out of range; set it to {want}")
        return float(v)

    return parse


def _integer(lo: int, hi: int | None = None, what: str = "") -> Parser:
    want = f"an integer {lo}..{hi}" if hi is not None else f"an integer >= {lo}"
    want += f" ({what})" if what else ""

    def parse(ctx: _Ctx, v: Any, path: KeyPath) -> int:
        if isinstance(v, bool) or not isinstance(v, int):
            ctx.fail(path, f"expected {want}, got {_type_name(v)}")
        if v < lo or (hi is not None and v > hi):
            ctx.fail(path, f"{v} is out of range; set it to {want}")
        return v

    return parse


def _string(null: bool = False) -> Parser:
    def parse(ctx: _Ctx, v: Any, path: KeyPath) -> str | None:
        if v is None and null:
            return None
        if not isinstance(v, str) or not v.strip():
            ctx.fail(path, f"expected a non-empty string, got {_type_name(v)} (quote values like '1')")
        return v

    return parse


def _one_of(*choices: str) -> Parser:
    def parse(ctx: _Ctx, v: Any, path: KeyPath) -> str:
        if v not in choices:
            close = difflib.get_close_matches(str(v), choices, n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            ctx.fail(path, f"got {_type_name(v)}; {hint}use one of: {', '.join(choices)}")
        return v

    return parse


def _vector(*dims: int) -> Parser:
    want = " or ".join(f"[{', '.join('xyz'[:d])}]" for d in dims)

    def parse(ctx: _Ctx, v: Any, path: KeyPath) -> tuple[float, ...]:
        if not isinstance(v, list) or len(v) not in dims:
            ctx.fail(
                path,
                f"expected {want} (ENU metres), got {_type_name(v)}"
                + (f" of {len(v)} numbers" if isinstance(v, list) else ""),
            )
        num = _number(unit="metres")
        return tuple(num(ctx, c, path + (i,)) for i, c in enumerate(v))

    return parse


def _list(item: Parser, what: str) -> Parser:
    def parse(ctx: _Ctx, v: Any, path: KeyPath) -> list[Any]:
        if not isinstance(v, list):
            ctx.fail(path, f"expected a list of {what}, got {_type_name(v)}")
        return [item(ctx, x, path + (i,)) for i, x in enumerate(v)]

    return parse


_HOSTPORT = r"(?P<host>\[[0-9a-fA-F:.]+\]|[A-Za-z0-9_.-]+):(?P<port>\d+)"
_CONNECTION_RES = (
    re.compile(r"sim"),
    re.compile(rf"(?:udp|udpout|udpin|tcp)://{_HOSTPORT}"),
    re.compile(r"serial://(?P<dev>/[^?\s]+)\?baud=(?P<baud>\d+)"),
)
_CONNECTION_FORMS = (
    "sim, udp://HOST:PORT, udpout://HOST:PORT, udpin://HOST:PORT, tcp://HOST:PORT, serial:///dev/NAME?baud=N"
)


def _connection(ctx: _Ctx, v: Any, path: KeyPath) -> str:
    if isinstance(v, str):
        for rx in _CONNECTION_RES:
            m = rx.fullmatch(v)
            if m is None:
                continue
            groups = m.groupdict()
            if "port" in groups and not 1 <= int(groups["port"]) <= 65535:
                ctx.fail(path, f"port {groups['port']} is out of range 1..65535")
            if "baud" in groups and int(groups["baud"]) <= 0:
                ctx.fail(path, "baud rate must be a positive integer, e.g. ?baud=57600")
            return v
    ctx.fail(path, f"{_type_name(v)} is not a connection URL; use one of {_CONNECTION_FORMS}")


_POINT_SPEC: dict[str, tuple[Parser, Any]] = {
    "position": (_vector(2, 3), None),
    "lat": (_number(ge=-90, le=90, unit="degrees"), None),
    "lon": (_number(ge=-180, le=180, unit="degrees"), None),
    "alt": (_number(unit="metres above the WGS84 ellipsoid"), None),
}


def _point(ctx: _Ctx, d: dict[str, Any], path: KeyPath, origin: Origin | None) -> Vec3:
    """A task-like position: ``position: [x, y(, z)]`` (ENU) or ``lat/lon(/alt)`` (needs origin)."""
    geodetic = [k for k in ("lat", "lon", "alt") if d[k] is not None]
    if d["position"] is not None:
        if geodetic:
            ctx.fail(path + (geodetic[0],), "give either 'position' (ENU metres) or lat/lon/alt, not both")
        p = d["position"]
        return (p[0], p[1], p[2] if len(p) == 3 else 0.0)
    if not geodetic:
        ctx.fail(
            path + ("position",),
            "required key is missing; add 'position: [x, y, z]' (ENU metres) or 'lat:', 'lon:' (and 'alt:')",
        )
    for k in ("lat", "lon"):
        if d[k] is None:
            ctx.fail(
                path + (k,),
                f"required key is missing; a geodetic position needs both lat and lon, add '{k}:'",
            )
    if origin is None:
        ctx.fail(
            path + ("lat",),
            "a lat/lon position needs the mission's 'origin: {lat, lon, alt}'; "
            "add an origin or give 'position: [x, y, z]' in ENU metres",
        )
    alt = d["alt"] if d["alt"] is not None else origin.alt
    return geodetic_to_local(d["lat"], d["lon"], alt, origin)


# --------------------------------------------------------------------------- the contract

_POS = _number(gt=0, unit="m/s")
_ACCEL = _number(gt=0, null=True, unit="m/s²")
_TIME = _number(ge=0, unit="seconds")
_ID = _string()
_OPT_STR = _string(null=True)

_ORIGIN = {
    "lat": (_number(ge=-90, le=90, unit="degrees"), _REQUIRED),
    "lon": (_number(ge=-180, le=180, unit="degrees"), _REQUIRED),
    "alt": (_number(unit="metres above the WGS84 ellipsoid"), _REQUIRED),
}
_CARRIER = {
    "id": (_ID, "carrier"),
    "connection": (_connection, "sim"),
    "sysid": (_integer(1, 255, "MAVLink system id"), 1),
    "position": (_vector(2), _REQUIRED),
    "heading_deg": (_number(unit="compass degrees, 0 = north, 90 = east"), 0.0),
    "max_speed": (_POS, _REQUIRED),
    "accel": (_ACCEL, None),
    "turn_rate": (_number(gt=0, null=True, unit="rad/s"), None),
    "unload_time": (_TIME, 0.0),
    "load_time": (_TIME, 0.0),
}
_ENERGY = {
    "initial": (_number(gt=0), _REQUIRED),
    "task": (_number(ge=0), _REQUIRED),
    "rho": (_number(gt=0, unit="metres per unit of energy"), _REQUIRED),
}
_FLEET = {
    "count": (_integer(1, 255, "number of rovers"), None),
    "sysid_start": (_integer(1, 255, "MAVLink system id of r1"), None),
}
_UNIT = {
    "id": (_ID, _REQUIRED),
    "sysid": (_integer(1, 255, "MAVLink system id"), _REQUIRED),
    "connection": (_connection, None),
}
_ROVERS = {
    "max_speed": (_POS, _REQUIRED),
    "accel": (_ACCEL, None),
    "deploy_range": (_number(gt=0, unit="metres"), None),
    "energy": (lambda c, v, p: c.section(v, p, _ENERGY), None),
    "endurance_range": (_number(gt=0, unit="metres"), None),
    "reserve": (_number(ge=0, lt=1, unit="fraction of the battery"), 0.1),
    "fleet": (lambda c, v, p: c.section(v, p, _FLEET), None),
    "units": (_list(lambda c, v, p: c.section(v, p, _UNIT), "units {id, sysid, connection}"), None),
}
_TASK = {"id": (_ID, _REQUIRED), **_POINT_SPEC}
_COLLECT_ROVER = {"id": (_ID, _REQUIRED), **_POINT_SPEC, "range": (_number(gt=0, unit="metres"), _REQUIRED)}
_COLLECTION = {
    "rovers": (
        _list(lambda c, v, p: c.section(v, p, _COLLECT_ROVER), "rovers {id, position, range}"),
        _REQUIRED,
    )
}
_FAULT = {
    "vehicle": (_OPT_STR, None),
    "kind": (_one_of(*FAULT_KINDS), _REQUIRED),
    "at": (_number(ge=0, unit="simulated seconds"), 0.0),
    "until": (_number(ge=0, null=True, unit="simulated seconds; omit = never back"), None),
    "rate": (_number(ge=0, le=1, unit="fraction of packets lost"), None),
    "seconds": (_number(ge=0, unit="added latency in seconds"), None),
    "factor": (_number(gt=0, unit="battery drain multiplier"), None),
    "level": (_number(ge=0, le=1, unit="fraction of a full battery"), None),
}
_FAULT_PARAM = {"packet_loss": "rate", "latency": "seconds", "battery_drain": "factor",
                "low_battery": "level"}
_SIM = {
    "speedup": (_number(gt=0, unit="simulated seconds per wall second"), 1.0),
    "faults": (_list(lambda c, v, p: c.section(v, p, _FAULT), "faults {vehicle, kind, ...}"), []),
}
_ENV_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def _env_name(ctx: _Ctx, v: Any, path: KeyPath) -> str:
    if not isinstance(v, str) or not _ENV_NAME.fullmatch(v):
        ctx.fail(path, f"{_type_name(v)} is not an environment variable name; use letters, digits and _ "
                       "(e.g. FLEET_SIGNING_KEY): the variable holds the key, the mission file only its name")
    return v


_SIGNING = {"key_env": (_env_name, _REQUIRED)}
_LINKS = {
    "heartbeat_timeout": (_number(gt=0, unit="seconds"), 3.0),
    "reassign_after": (_number(ge=0, unit="seconds"), 10.0),
    "signing": (lambda c, v, p: SigningConfig(**c.section(v, p, _SIGNING)), None),
    "failsafe": (_one_of(*FAILSAFE_ACTIONS), "keep"),
}
_XI = _number(ge=0)
_ROADMAP = {
    "xi1": (_XI, None),
    "xi2": (_XI, None),
    "xi3": (_XI, None),
    "xi4": (_XI, None),
    "phi": (_number(gt=0, lt=1), None),
}
_PLANNER = {
    "deploy": (_ID, "lee"),
    "collect": (_ID, "lee"),
    "seed": (_integer(0), 0),
    "roadmap": (lambda c, v, p: RoadmapConfig(**c.section(v, p, _ROADMAP)), None),
}
_TLS = {"ca": (_OPT_STR, None), "cert": (_OPT_STR, None), "key": (_OPT_STR, None)}
_MQTT_URL = re.compile(r"mqtts?://[A-Za-z0-9_.-]+(:\d{1,5})?/?")


def _mqtt_url(ctx: _Ctx, v: Any, path: KeyPath) -> str:
    if not isinstance(v, str) or not _MQTT_URL.fullmatch(v):
        ctx.fail(
            path, f"{_type_name(v)} is not an MQTT broker URL; use mqtt://HOST[:PORT] or mqtts://HOST[:PORT]"
        )
    return v


_MQTT = {
    "url": (_mqtt_url, _REQUIRED),
    "topic_prefix": (_OPT_STR, None),
    "client_id": (_OPT_STR, None),
    "username": (_OPT_STR, None),
    "password_env": (_OPT_STR, None),
    "tls": (lambda c, v, p: TlsConfig(**c.section(v, p, _TLS)), None),
}
_TOP = {
    "name": (_ID, None),
    "origin": (lambda c, v, p: Origin(**c.section(v, p, _ORIGIN)), None),
    "carrier": (lambda c, v, p: c.section(v, p, _CARRIER), _REQUIRED),
    "rovers": (lambda c, v, p: c.section(v, p, _ROVERS), _REQUIRED),
    "tasks": (_list(lambda c, v, p: c.section(v, p, _TASK), "tasks {id, position}"), _REQUIRED),
    "obstacles": (_list(_list(_vector(2), "[x, y] vertices"), "polygons"), []),
    "bounds": (_list(_vector(2), "two corners [[xmin, ymin], [xmax, ymax]]"), None),
    "collection": (lambda c, v, p: c.section(v, p, _COLLECTION), None),
    "sim": (lambda c, v, p: c.section(v, p, _SIM), {"speedup": 1.0, "faults": []}),
    "links": (lambda c, v, p: LinksConfig(**c.section(v, p, _LINKS)), LinksConfig()),
    "planner": (lambda c, v, p: PlannerConfig(**c.section(v, p, _PLANNER)), PlannerConfig()),
    "dwell": (_number(ge=0, unit="seconds on task"), 60.0),
    "mqtt": (lambda c, v, p: c.section(v, p, _MQTT), None),
    "geofence": (lambda c, v, p: c.section(v, p, _GEOFENCE), None),
}


# --------------------------------------------------------------------------- cross-field rules


def _unique(ctx: _Ctx, items: list[tuple[Any, KeyPath]], what: str) -> None:
    seen: dict[Any, KeyPath] = {}
    for value, path in items:
        if value in seen:
            ctx.fail(
                path,
                f"duplicate {what} {value!r} (also at {_fmt_path(seen[value])}); make every {what} unique",
            )
        seen[value] = path


def _build_fleet(
    ctx: _Ctx, r: dict[str, Any], carrier: dict[str, Any], default_count: int
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


def _polygon(ctx: _Ctx, pts: list[Vec2], path: KeyPath) -> Polygon:
    if len(pts) < 3:
        ctx.fail(path, f"an obstacle polygon needs at least 3 vertices [x, y], got {len(pts)}")
    poly = Polygon(pts)
    if poly.convex_hull.area <= 0.0 or not poly.is_valid or poly.area <= 0.0:
        flat = poly.convex_hull.area <= 0.0
        reason = "zero area: collinear or repeated vertices" if flat else explain_validity(poly)
        ctx.fail(
            path,
            f"invalid polygon ({reason}); list the vertices in order around the outline "
            "without self-crossings",
        )
    return poly


def _check_geometry(
    ctx: _Ctx, d: dict[str, Any], tasks: tuple[Task, ...]
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
    polys = [_polygon(ctx, pts, ("obstacles", i)) for i, pts in enumerate(d["obstacles"])]
    if polys and bounds is None:
        ctx.fail(
            ("bounds",),
            "obstacles need a workspace for roadmap sampling; add 'bounds: [[xmin, ymin], [xmax, ymax]]'",
        )
    points: list[tuple[str, Vec2, KeyPath]] = [
        ("the carrier's start", d["carrier"]["position"], ("carrier", "position"))
    ]
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
            if poly.covers(Point(x, y)):
                ctx.fail(
                    path, f"{what} at ({x:g}, {y:g}) lies inside obstacles[{j}]; move it out of the obstacle"
                )
    obstacles = tuple(tuple((float(p[0]), float(p[1])) for p in pts) for pts in d["obstacles"])
    return obstacles, bounds


# --- geofence (docs/field-safety.md): one inclusion polygon, obstacles as exclusion zones -----------
def _fence_vertex(ctx: _Ctx, v: Any, path: KeyPath) -> Any:
    if isinstance(v, dict):
        return ctx.section(v, path, {"lat": _ORIGIN["lat"], "lon": _ORIGIN["lon"]})
    if isinstance(v, list):
        return _vector(2)(ctx, v, path)
    ctx.fail(path, f"expected a vertex [x, y] (ENU metres) or {{lat, lon}}, got {_type_name(v)}")


_GEOFENCE: dict[str, tuple[Parser, Any]] = {
    "polygon": (_list(_fence_vertex, "vertices [x, y] or {lat, lon}"), None),
    "from": (_one_of("bounds"), None),
    "alt_max": (_number(gt=0, null=True, unit="metres above home"), None),
    "action": (_one_of(*FENCE_ACTIONS), "report"),
}


def _geofence(ctx: _Ctx, d: dict[str, Any], tasks: tuple[Task, ...], obstacles: tuple[tuple[Vec2, ...], ...],
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
        poly = Polygon(pts) if len(pts) >= 3 else None
        if poly is None or not poly.is_valid or poly.area <= 0.0:
            why = f"{len(pts)} vertices" if poly is None else explain_validity(poly)
            ctx.fail(("geofence", "polygon"), f"not a usable polygon ({why}); list at least 3 vertices in "
                     "order around the outline without self-crossings")
    poly = Polygon(pts)
    where = ("geofence", "polygon") if g["polygon"] is not None else ("geofence", "from")
    inside = [("the carrier's start", tuple(d["carrier"]["position"][:2]))]
    inside += [(f"task {t.id!r}", t.position[:2]) for t in tasks]
    for what, (x, y) in inside:
        if not poly.covers(Point(x, y)):
            ctx.fail(where, f"{what} at ({x:g}, {y:g}) lies outside the geofence; "
                     "widen the polygon or move it")
    for t in tasks:
        if g["alt_max"] is not None and t.position[2] > g["alt_max"]:
            ctx.fail(("geofence", "alt_max"), f"task {t.id!r} is {t.position[2]:g} m high, above alt_max "
                     f"{g['alt_max']:g} m; raise alt_max or lower the task")
    return GeofenceConfig(tuple(pts), obstacles, g["alt_max"], g["action"])


def _build(ctx: _Ctx, data: Any, path: Path | None) -> Mission:
    if data is None:
        ctx.fail((), "the mission file is empty; see DESIGN.md 'Mission file (YAML)' for the keys")
    d = ctx.section(data, (), _TOP)
    origin: Origin | None = d["origin"]
    carrier, r = d["carrier"], d["rovers"]

    tasks = tuple(Task(t["id"], _point(ctx, t, ("tasks", i), origin)) for i, t in enumerate(d["tasks"]))
    collection = None
    if d["collection"] is not None:
        rows = d["collection"]["rovers"]
        if not rows:
            ctx.fail(
                ("collection", "rovers"),
                "the list is empty; list the rovers to collect {id, position, range}",
            )
        collection = tuple(
            CollectRover(c["id"], _point(ctx, c, ("collection", "rovers", i), origin), c["range"])
            for i, c in enumerate(rows)
        )
    if not tasks and collection is None:
        ctx.fail(
            ("tasks",),
            "the task list is empty; add at least one task {id, position} "
            "(an empty list is allowed only in a collection-only mission with a 'collection' section)",
        )
    _unique(ctx, [(t.id, ("tasks", i, "id")) for i, t in enumerate(tasks)], "task id")

    # deploy range: given, or from energy terms (dissertation ch. 3.2)
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
    else:
        deploy_range = r["deploy_range"]
    endurance = r["endurance_range"]
    if endurance is None:
        endurance = energy.rho * energy.initial if energy is not None else 2.0 * deploy_range
    elif endurance < deploy_range:
        ctx.fail(
            ("rovers", "endurance_range"),
            f"{endurance:g} m on a full battery is less than the deploy range "
            f"{deploy_range:g} m; raise endurance_range or lower deploy_range",
        )

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

    n_default = len(tasks) if tasks else len(collection or ())
    units = _build_fleet(ctx, r, carrier, n_default)
    fleet_key = ("rovers", "units") if r["units"] is not None else ("rovers", "fleet", "count")
    if len(units) < len(tasks):
        ctx.fail(
            fleet_key,
            f"only {len(units)} rover(s) for {len(tasks)} tasks; every task needs its own rover, "
            f"give at least {len(tasks)} rovers",
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
    _unique(
        ctx,
        [(carrier["sysid"], ("carrier", "sysid"))]
        + [(u.sysid, unit_path(i, "sysid")) for i, u in enumerate(units)],
        "vehicle sysid",
    )
    rover_ids = {u.id for u in units}
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

    obstacles, bounds = _check_geometry(ctx, d, tasks)
    geofence = _geofence(ctx, d, tasks, obstacles, bounds, origin)

    faults = []
    vehicles = rover_ids | {carrier["id"]}
    for i, f in enumerate(d["sim"]["faults"]):
        fp: KeyPath = ("sim", "faults", i)
        if f["vehicle"] is not None and f["vehicle"] not in vehicles:
            ctx.fail(
                fp + ("vehicle",),
                f"{f['vehicle']!r} is not a vehicle of this mission "
                f"({', '.join(sorted(vehicles))}); omit 'vehicle' to affect every vehicle",
            )
        needed = _FAULT_PARAM.get(f["kind"])
        for param in _FAULT_PARAM.values():
            if param != needed and f[param] is not None:
                ctx.fail(fp + (param,), f"'{param}' does not apply to kind {f['kind']}; remove it")
        if needed is not None and f[needed] is None:
            ctx.fail(fp + (needed,), f"required key is missing; kind {f['kind']} needs '{needed}:'")
        if f["until"] is not None and f["until"] <= f["at"]:
            ctx.fail(fp + ("until",), f"until ({f['until']:g} s) must be later than at ({f['at']:g} s)")
        faults.append(Fault(**f))

    mqtt = None
    if d["mqtt"] is not None:
        m = dict(d["mqtt"])
        tls: TlsConfig | None = m["tls"]
        if tls is not None and (tls.cert is None) != (tls.key is None):
            ctx.fail(
                ("mqtt", "tls", "cert" if tls.cert is None else "key"),
                "a client certificate needs both 'cert' and 'key'; add the missing one",
            )
        name_for_topic = d["name"] or (path.stem if path else "mission")
        m["topic_prefix"] = m["topic_prefix"] or f"fleetctl/{name_for_topic}"
        mqtt = MqttConfig(**m)

    mission = Mission(
        name=d["name"] or (path.stem if path is not None else "mission"),
        origin=origin,
        carrier=CarrierConfig(**{**carrier, "position": tuple(carrier["position"])}),
        rovers=RoversConfig(r["max_speed"], r["accel"], deploy_range, endurance, r["reserve"], units, energy),
        tasks=tasks,
        obstacles=obstacles,
        bounds=bounds,
        collection=collection,
        sim=SimConfig(d["sim"]["speedup"], tuple(faults)),
        links=d["links"],
        planner=d["planner"],
        dwell=d["dwell"],
        mqtt=mqtt,
        raw=copy.deepcopy(data),
        path=path,
        geofence=geofence,
    )
    log.debug(
        "mission %s: %d tasks, %d rovers, d_deploy %.2f m", mission.name, len(tasks), len(units), deploy_range
    )
    return mission


# --------------------------------------------------------------------------- YAML with line numbers


def _line_map(ctx: _Ctx, node: yaml.Node, path: KeyPath, lines: dict[KeyPath, int]) -> None:
    """Record the 1-based line of every key path; reject duplicate keys in a mapping."""
    if isinstance(node, yaml.MappingNode):
        seen: set[Any] = set()
        for key_node, value_node in node.value:
            key = key_node.value
            if key in seen:
                lines[path + (key,)] = key_node.start_mark.line + 1
                ctx.fail(path + (key,), "duplicate key in the same mapping; keep only one")
            seen.add(key)
            lines[path + (key,)] = key_node.start_mark.line + 1
            _line_map(ctx, value_node, path + (key,), lines)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            lines[path + (i,)] = item.start_mark.line + 1
            _line_map(ctx, item, path + (i,), lines)


def parse_mission(data: dict[str, Any], source: str) -> Mission:
    """Validate an already parsed mission mapping; ``source`` names it in error messages."""
    return _build(_Ctx(source), data, None)


def load_mission(path: str | Path) -> Mission:
    """Read, parse and validate a mission YAML file. Raises :class:`MissionError` on any problem."""
    path = Path(path)
    source = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise MissionError(f"{source}: cannot read the mission file: {exc}") from None
    ctx = _Ctx(source)
    try:
        loader = yaml.SafeLoader(text)
        try:
            node = loader.get_single_node()
            data = loader.construct_document(node) if node is not None else None
        finally:
            loader.dispose()
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
    if node is not None:
        lines: dict[KeyPath, int] = {}
        ctx.lines = lines
        _line_map(ctx, node, (), lines)
    return _build(ctx, data, path)
