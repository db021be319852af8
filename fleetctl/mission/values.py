"""The mission loader's value parsers: each checks one value of a mission file and raises
:class:`fleetctl.mission.model.MissionError` through :class:`Ctx` with the file, line and key path.

A parser is ``parse(ctx, value, path) -> parsed``; :meth:`Ctx.section` checks a mapping against a
spec (key -> (parser, default or ``REQUIRED``)). The specs of the mission file are in
:mod:`fleetctl.mission.schema`; the cross-field rules and the typed mission in
:mod:`fleetctl.mission.loader`.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Callable, Mapping
from typing import Any, NoReturn

import fleetctl.mission.limits as L
from fleetctl.geo import Origin, geodetic_to_local
from fleetctl.mission.connections import ConnectionSpellingError, normalize_connection
from fleetctl.mission.model import MissionError, Vec3

KeyPath = tuple[str | int, ...]

REQUIRED = object()
Parser = Callable[["Ctx", Any, KeyPath], Any]


def fmt_path(path: KeyPath) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "(top level)"


def short(text: str, n: int = 60) -> str:
    """``repr`` of a string, cut to about ``n`` characters for a message."""
    return repr(text) if len(text) <= n else repr(text[:n]) + f"... ({len(text)} characters)"


def type_name(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"a boolean ({str(value).lower()})"
    if isinstance(value, int) and value.bit_length() > 64:
        return f"an integer of about {int(value.bit_length() * 0.30103) + 1} digits"
    if isinstance(value, int | float):
        return f"a number ({value})"
    if isinstance(value, str):
        return f"a string ({short(value)})"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, dict):
        return "a mapping"
    return type(value).__name__


class Ctx:
    def __init__(self, source: str, lines: Mapping[KeyPath, int] | None = None) -> None:
        self.source = source
        self.lines = lines or {}
        self.raw: Any = None
        self.notes: dict[KeyPath, str] = {}  # key path -> where it came from (a task file's feature)

    def fail(self, path: KeyPath, message: str) -> NoReturn:
        where = self.source
        for n in range(len(path), -1, -1):  # the line of the key, or of its nearest parent
            if path[:n] in self.lines:
                where = f"{self.source}:{self.lines[path[:n]]}"
                break
        note = next((self.notes[path[:n]] for n in range(len(path), 0, -1) if path[:n] in self.notes), None)
        shown = fmt_path(path) + (f" (from {note})" if note else "")
        raise MissionError(f"{where}: {shown}: {message}")

    def section(self, value: Any, path: KeyPath, spec: Mapping[str, tuple[Parser, Any]]) -> dict[str, Any]:
        """Check a mapping against ``spec`` (key → (parser, default or REQUIRED)); parse every key."""
        if not isinstance(value, dict):
            self.fail(path, f"expected a mapping with keys {', '.join(spec)}, got {type_name(value)}")
        for key in value:
            if key not in spec:
                close = difflib.get_close_matches(str(key), list(spec), n=1)
                hint = f"did you mean '{close[0]}'? " if close else ""
                self.fail(path + (str(key),), f"unknown key; {hint}allowed keys here: {', '.join(spec)}")
        out: dict[str, Any] = {}
        for key, (parse, default) in spec.items():
            if key in value:
                out[key] = parse(self, value[key], path + (key,))
            elif default is REQUIRED:
                self.fail(path + (key,), f"required key is missing; add '{key}:' to {fmt_path(path)}")
            else:
                out[key] = default
        return out


_FLOATISH = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+")


def number(
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
    want = "a number " + " and ".join(limits) if limits else "a number"
    want = want + (f" ({unit})" if unit else "") + (" or null" if null else "")

    def parse(ctx: Ctx, v: Any, path: KeyPath) -> float | None:
        if v is None and null:
            return None
        if isinstance(v, int) and not isinstance(v, bool) and not -1e300 < v < 1e300:  # any length
            ctx.fail(path, f"{type_name(v)} is out of range; set it to {want}")
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            hint = ""
            if isinstance(v, str) and _FLOATISH.fullmatch(v.strip()):
                hint = " (YAML reads 1e20 as text: write 1.0e+20)"
            ctx.fail(path, f"expected {want}, got {type_name(v)}{hint}")
        x = float(v)  # an int of any size was compared above: now safe
        bad = (
            (gt is not None and not x > gt)
            or (ge is not None and not x >= ge)
            or (lt is not None and not x < lt)
            or (le is not None and not x <= le)
        )
        if bad:
            shown = v if not isinstance(v, int) or v.bit_length() <= 64 else type_name(v)
            ctx.fail(path, f"{shown} is out of range; set it to {want}")
        return x

    return parse


def integer(lo: int, hi: int | None = None, what: str = "") -> Parser:
    want = f"an integer {lo}..{hi}" if hi is not None else f"an integer >= {lo}"
    want += f" ({what})" if what else ""

    def parse(ctx: Ctx, v: Any, path: KeyPath) -> int:
        if isinstance(v, bool) or not isinstance(v, int):
            ctx.fail(path, f"expected {want}, got {type_name(v)}")
        if v < lo or (hi is not None and v > hi):
            shown = v if v.bit_length() <= 64 else type_name(v)
            ctx.fail(path, f"{shown} is out of range; set it to {want}")
        return v

    return parse


def string(null: bool = False) -> Parser:
    def parse(ctx: Ctx, v: Any, path: KeyPath) -> str | None:
        if v is None and null:
            return None
        if not isinstance(v, str) or not v.strip():
            ctx.fail(path, f"expected a non-empty string, got {type_name(v)} (quote values like '1')")
        if len(v) > L.MAX_STRING:
            ctx.fail(path, f"a string of {len(v)} characters is too long; use at most {L.MAX_STRING}")
        return v

    return parse


def one_of(*choices: str) -> Parser:
    def parse(ctx: Ctx, v: Any, path: KeyPath) -> str:
        if v not in choices:
            close = difflib.get_close_matches(str(v), choices, n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            ctx.fail(path, f"got {type_name(v)}; {hint}use one of: {', '.join(choices)}")
        return v

    return parse


def vector(*dims: int) -> Parser:
    want = " or ".join(f"[{', '.join('xyz'[:d])}]" for d in dims)

    def parse(ctx: Ctx, v: Any, path: KeyPath) -> tuple[float, ...]:
        if not isinstance(v, list) or len(v) not in dims:
            ctx.fail(
                path,
                f"expected {want} (ENU metres), got {type_name(v)}"
                + (f" of {len(v)} numbers" if isinstance(v, list) else ""),
            )
        return tuple(COORD(ctx, c, path + (i,)) for i, c in enumerate(v))

    return parse


def list_of(item: Parser, what: str, max_len: int) -> Parser:
    def parse(ctx: Ctx, v: Any, path: KeyPath) -> list[Any]:
        if not isinstance(v, list):
            ctx.fail(path, f"expected a list of {what}, got {type_name(v)}")
        if len(v) > max_len:
            ctx.fail(path, f"{len(v)} entries are too many; give at most {max_len} {what} "
                           "(see docs/mission-limits.md)")
        return [item(ctx, x, path + (i,)) for i, x in enumerate(v)]

    return parse


COORD = number(ge=-L.MAX_COORD, le=L.MAX_COORD, unit="metres")
ALT = number(ge=L.MIN_ALT, le=L.MAX_ALT, unit="metres above the WGS84 ellipsoid")

_HOSTPORT = r"(?P<host>\[[0-9a-fA-F:.]+\]|[A-Za-z0-9_.-]+):(?P<port>\d+)"
_CONNECTION_RES = (
    re.compile(r"sim"),
    re.compile(rf"(?:udp|udpout|udpin|tcp)://{_HOSTPORT}"),
    re.compile(r"serial://(?P<dev>/[^?\s]+|COM\d+)\?baud=(?P<baud>\d+)"),
)
_CONNECTION_FORMS = (
    "sim, udp://HOST:PORT, udpout://HOST:PORT, udpin://HOST:PORT, tcp://HOST:PORT, serial:///dev/NAME?baud=N "
    "(docs/mavlink.md)"
)


def connection_url(ctx: Ctx, v: Any, path: KeyPath) -> str:
    if isinstance(v, str):
        try:  # MAVSDK/pymavlink/MAVProxy spellings: fleetctl's own, or what to write instead
            v = normalize_connection(v)
        except ConnectionSpellingError as exc:
            ctx.fail(path, str(exc))
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
    ctx.fail(path, f"{type_name(v)} is not a connection URL; use one of {_CONNECTION_FORMS}")


POINT_SPEC: dict[str, tuple[Parser, Any]] = {
    "position": (vector(2, 3), None),
    "lat": (number(ge=-90, le=90, unit="degrees"), None),
    "lon": (number(ge=-180, le=180, unit="degrees"), None),
    "alt": (ALT, None),
}


def point(ctx: Ctx, d: dict[str, Any], path: KeyPath, origin: Origin | None) -> Vec3:
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
    p = geodetic_to_local(d["lat"], d["lon"], alt, origin)
    if not all(abs(c) <= L.MAX_COORD for c in p):
        ctx.fail(path + ("lat",), f"lat/lon/alt lie ({p[0]:.0f}, {p[1]:.0f}, {p[2]:.0f}) m from the origin, "
                                  f"farther than {L.MAX_COORD:g} m; move the position or the origin")
    return p


POS = number(ge=L.MIN_SPEED, le=L.MAX_SPEED, unit="m/s")
ACCEL = number(ge=L.MIN_ACCEL, le=L.MAX_ACCEL, null=True, unit="m/s²")
TIME = number(ge=0, le=L.MAX_HANDLING_TIME, unit="seconds")
RANGE = number(ge=L.MIN_RANGE, le=L.MAX_RANGE, unit="metres")
ID = string()
OPT_STR = string(null=True)

_ENV_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def env_name(ctx: Ctx, v: Any, path: KeyPath) -> str:
    if not isinstance(v, str) or not _ENV_NAME.fullmatch(v):
        ctx.fail(path, f"{type_name(v)} is not an environment variable name; use letters, digits and _ "
                       "(e.g. FLEET_SIGNING_KEY): the variable holds the key, the mission file only its name")
    return v


def boolean(ctx: Ctx, v: Any, path: KeyPath) -> bool:
    if not isinstance(v, bool):
        ctx.fail(path, f"expected true or false, got {type_name(v)}")
    return v


_MQTT_URL = re.compile(r"mqtts?://[A-Za-z0-9_.-]+(:\d{1,5})?/?")


def mqtt_url(ctx: Ctx, v: Any, path: KeyPath) -> str:
    if not isinstance(v, str) or not _MQTT_URL.fullmatch(v):
        ctx.fail(
            path, f"{type_name(v)} is not an MQTT broker URL; use mqtt://HOST[:PORT] or mqtts://HOST[:PORT]"
        )
    return v


class FileRef(str):
    """``{file: PATH}`` in place of a list (tasks, obstacles): read in :func:`read_files`."""


def file_ref(ctx: Ctx, v: Any, path: KeyPath) -> FileRef:
    return FileRef(ctx.section(v, path, {"file": (string(), REQUIRED)})["file"])
