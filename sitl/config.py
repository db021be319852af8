"""Plain configuration of a simulated fleet, and its reading from a parsed mission-file dict.

sitl is independent of the controller package: ``FleetConfig.from_mission_dict`` takes the raw
YAML mapping of a mission file (see docs/mission-file.md) and keeps only what the
simulation needs. Keys the simulation does not use (tasks, planner, obstacles, ...) are ignored
here; validating them is the mission loader's job.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from .faults import Fault, FaultError
from .signing import key_from_env

AUTOPILOTS = ("px4", "ardupilot")
CARRIER_FRAMES = ("ground", "multirotor")


class ConfigError(ValueError):
    """A configuration the simulated fleet cannot run; the message names the key and the fix."""


@dataclass
class VehicleSpec:
    """One simulated vehicle. Positions are ENU metres relative to the fleet origin.

    ``connection`` is written from the controller's side (``sim``, ``udp://H:P``, ``udpout://H:P``,
    ``udpin://H:P``); None for a rover means: share the carrier's link.
    """

    id: str
    sysid: int
    role: str  # "carrier" | "rover"
    max_speed: float
    accel: float | None = None
    connection: str | None = None
    position: tuple[float, float, float] | None = None  # None for a rover = loaded on the carrier
    heading_deg: float = 0.0
    turn_rate: float | None = None  # carrier only, rad/s; None = instantaneous
    climb_rate: float | None = None  # rover only, m/s; None = max_speed
    land_speed: float | None = None  # rover only, m/s; None = climb rate
    endurance_range: float | None = None  # rover only, metres of flight on a full battery; None = no drain
    frame: str = "multirotor"  # carrier: "ground" | "multirotor"; rovers are multirotors
    compid: int = 1
    carrier: str | None = None  # rover only: the carrier it starts on, whose link it shares (None: the first)

    def __post_init__(self) -> None:
        where = f"vehicle {self.id!r}"
        if not 1 <= int(self.sysid) <= 255:
            raise ConfigError(f"{where}: sysid must be 1..255, got {self.sysid}")
        if self.role not in ("carrier", "rover"):
            raise ConfigError(f"{where}: role must be 'carrier' or 'rover'")
        _positive(self.max_speed, f"{where}: max_speed")
        for name in ("accel", "turn_rate", "climb_rate", "land_speed", "endurance_range"):
            val = getattr(self, name)
            if val is not None:
                _positive(val, f"{where}: {name}")
        if self.role == "carrier" and self.frame not in CARRIER_FRAMES:
            raise ConfigError(f"{where}: frame must be one of {CARRIER_FRAMES}, got {self.frame!r}")


@dataclass
class FleetConfig:
    """Everything the simulated fleet needs. Time values are simulated seconds unless noted."""

    origin: tuple[float, float, float]  # lat, lon (degrees), alt (m AMSL) of the ENU origin
    carrier: VehicleSpec  # the first carrier (the only one of a one-carrier fleet)
    rovers: list[VehicleSpec] = field(default_factory=list)
    more_carriers: list[VehicleSpec] = field(default_factory=list)  # several carriers: the others
    speedup: float = 1.0  # simulated seconds per wall second
    seed: int = 0
    faults: list[Fault] = field(default_factory=list)
    autopilot: str = "px4"  # "px4" | "ardupilot": HEARTBEAT, modes, mission item 0 = home
    step: float = 0.05  # simulated seconds per physics step
    tick_hz: float = 50.0  # wall-clock rate of the simulation loop (streams are scheduled on it)
    position_hz: float = 10.0  # default GLOBAL_POSITION_INT rate (wall Hz), SET_MESSAGE_INTERVAL overrides
    name: str = "sim"
    signing_key: bytes | None = field(default=None, repr=False)  # 32 bytes: every vehicle signs/verifies

    def __post_init__(self) -> None:
        _positive(self.speedup, "sim.speedup")
        _positive(self.step, "step")
        _positive(self.tick_hz, "tick_hz")
        _positive(self.position_hz, "position_hz")
        if self.signing_key is not None and len(self.signing_key) != 32:
            raise ConfigError("signing_key: a MAVLink signing key is 32 bytes")
        if self.autopilot not in AUTOPILOTS:
            raise ConfigError(f"sim.autopilot: use one of {AUTOPILOTS}, got {self.autopilot!r}")
        for c in self.carriers:
            if c.role != "carrier":
                raise ConfigError(f"carrier {c.id!r}: its role must be 'carrier'")
        carrier_ids = {c.id for c in self.carriers}
        for r in self.rovers:
            if r.carrier is not None and r.carrier not in carrier_ids:
                raise ConfigError(f"rover {r.id!r}: no carrier {r.carrier!r} in the fleet")
        seen_ids: set[str] = set()
        for v in self.vehicles:
            if v.id in seen_ids:
                raise ConfigError(f"vehicle id {v.id!r} is used twice")
            seen_ids.add(v.id)
        groups, by_id = self.link_groups(), {v.id: v for v in self.vehicles}
        for key, ids in groups.items():  # system ids are unique per link, not per fleet
            seen_sysids: dict[int, str] = {}
            for vid in ids:
                sysid = by_id[vid].sysid
                if sysid in seen_sysids:
                    where = "" if len(groups) == 1 else f" on link {key!r}"
                    raise ConfigError(f"sysid {sysid} is used twice{where} (vehicles {seen_sysids[sysid]!r} "
                                      f"and {vid!r})")
                seen_sysids[sysid] = vid
        for f in self.faults:
            if f.vehicle is not None and f.vehicle not in seen_ids:
                raise ConfigError(f"sim.faults: vehicle {f.vehicle!r} is not in the fleet")

    @property
    def carriers(self) -> list[VehicleSpec]:
        """Every carrier, the first one first."""
        return [self.carrier, *self.more_carriers]

    @property
    def vehicles(self) -> list[VehicleSpec]:
        return [*self.carriers, *self.rovers]

    def link_groups(self) -> dict[str, list[str]]:
        """Link key -> the ids of the vehicles on it (one UDP endpoint each), in fleet order: vehicles
        with the same URL share one; a rover without a connection shares its carrier's; each ``sim``
        connection is a link of its own (key ``sim#<vehicle id>``, a free loopback port). System ids
        are unique per link."""

        def carrier_key(c: VehicleSpec) -> str:
            return c.connection if c.connection not in (None, "sim") else f"sim#{c.id}"

        groups: dict[str, list[str]] = {}
        for spec in self.vehicles:
            if spec.role == "carrier":
                key = carrier_key(spec)
            elif spec.connection is None:
                key = carrier_key(self.home_of(spec))
            elif spec.connection == "sim":
                key = f"sim#{spec.id}"
            else:
                key = spec.connection
            groups.setdefault(key, []).append(spec.id)
        return groups

    def home_of(self, rover: VehicleSpec) -> VehicleSpec:
        """The carrier ``rover`` starts on and whose link it shares."""
        return next((c for c in self.carriers if c.id == rover.carrier), self.carrier)

    @classmethod
    def from_mission_dict(
        cls,
        d: Mapping[str, Any],
        *,
        speedup: float | None = None,
        seed: int | None = None,
        autopilot: str | None = None,
        signing_key: bytes | None = None,
        signing_from_env: bool = True,
    ) -> FleetConfig:
        """Build the fleet of a parsed mission file. Keyword arguments override the file
        (e.g. ``--speedup`` on the command line).

        Read: ``origin``, ``carrier`` (id, connection, sysid, position, heading_deg, max_speed, accel,
        turn_rate, optional frame), ``rovers`` (max_speed, accel, endurance_range, optional
        climb_rate/land_speed, ``fleet: {count, sysid_start}`` or ``units: [{id, sysid, connection,
        position?}]``), ``sim`` (speedup, faults; optional seed, autopilot, position_hz) and
        ``planner.seed`` as the seed fallback.

        Signing: ``signing_key`` (32 bytes) provisions every vehicle; without it, and with
        ``signing_from_env``, a mission with ``links.signing.key_env`` provisions them with the key in
        that environment variable (as the controller reads it) - the mission loader validates the key.
        """
        if not isinstance(d, Mapping):
            raise ConfigError("mission: expected a mapping at the top level")
        if "carriers" in d:
            raise ConfigError("carriers: a mission with several carriers is served by "
                              "'fleetctl sim --mission FILE' (its loader builds the fleet)")
        lat, lon, alt = _origin(d)
        carrier = _carrier(_mapping(d.get("carrier"), "carrier"))
        rovers = _rovers(_mapping(d.get("rovers"), "rovers"), carrier)
        sim = _mapping(d.get("sim") or {}, "sim")
        faults = _faults(sim)
        raw_planner = d.get("planner")
        planner: Mapping[str, Any] = raw_planner if isinstance(raw_planner, Mapping) else {}
        seed_val = seed if seed is not None else sim.get("seed", planner.get("seed", 0))
        kw = _signing(d, signing_key, signing_from_env)
        if sim.get("position_hz") is not None:
            kw["position_hz"] = _num(sim["position_hz"], "sim.position_hz")
        return cls(
            origin=(lat, lon, alt),
            carrier=carrier,
            rovers=rovers,
            speedup=speedup if speedup is not None else _pos_num(sim.get("speedup", 1.0), "sim.speedup"),
            seed=_int(seed_val, "sim.seed"),
            faults=faults,
            autopilot=autopilot or str(sim.get("autopilot", "px4")),
            name=str(d.get("name", "sim")),
            **kw,
        )


def _origin(d: Mapping[str, Any]) -> tuple[float, float, float]:
    if d.get("origin") is None:
        raise ConfigError("origin: the simulated fleet needs the mission's origin to place the vehicles "
                          "on the globe; add  origin: {lat: ..., lon: ..., alt: ...}  to the mission")
    origin = _mapping(d.get("origin"), "origin")
    try:
        lat, lon = float(origin["lat"]), float(origin["lon"])
        alt = float(origin.get("alt", 0.0))
    except (KeyError, TypeError, ValueError):
        raise ConfigError("origin: needs numbers lat, lon (degrees) and alt (m)") from None
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        raise ConfigError(f"origin: lat/lon out of range ({lat}, {lon})")
    return lat, lon, alt


def _carrier(c: Mapping[str, Any]) -> VehicleSpec:
    return VehicleSpec(
        id=str(c.get("id", "carrier")),
        sysid=_int(c.get("sysid", 1), "carrier.sysid"),
        role="carrier",
        connection=str(c.get("connection", "sim")),
        position=_position(c.get("position", (0.0, 0.0)), "carrier.position", ground=True),
        heading_deg=_num(c.get("heading_deg", 0.0), "carrier.heading_deg"),
        max_speed=_pos_num(c.get("max_speed"), "carrier.max_speed"),
        accel=_opt_pos(c.get("accel"), "carrier.accel"),
        turn_rate=_opt_pos(c.get("turn_rate"), "carrier.turn_rate"),
        frame=str(c.get("frame", "ground")),
    )


def _rovers(r: Mapping[str, Any], carrier: VehicleSpec) -> list[VehicleSpec]:
    max_speed = _pos_num(r.get("max_speed"), "rovers.max_speed")
    accel = _opt_pos(r.get("accel"), "rovers.accel")
    climb_rate = _opt_pos(r.get("climb_rate"), "rovers.climb_rate")
    land_speed = _opt_pos(r.get("land_speed"), "rovers.land_speed")
    endurance_range = _opt_pos(r.get("endurance_range"), "rovers.endurance_range")

    def spec(vid: str, sysid: int, connection: str | None = None,
             position: tuple[float, float, float] | None = None) -> VehicleSpec:
        return VehicleSpec(id=vid, sysid=sysid, role="rover", connection=connection, position=position,
                           max_speed=max_speed, accel=accel, climb_rate=climb_rate, land_speed=land_speed,
                           endurance_range=endurance_range)

    if "units" in r and r["units"] is not None:
        units = r["units"]
        if not isinstance(units, list) or not units:
            raise ConfigError("rovers.units: expected a non-empty list of {id, sysid, connection}")
        rovers = []
        for i, u in enumerate(units):
            u = _mapping(u, f"rovers.units[{i}]")
            if "id" not in u or "sysid" not in u:
                raise ConfigError(f"rovers.units[{i}]: needs id and sysid")
            pos = u.get("position")
            rovers.append(spec(
                str(u["id"]),
                _int(u["sysid"], f"rovers.units[{i}].sysid"),
                connection=None if u.get("connection") is None else str(u["connection"]),
                position=None if pos is None else _position(pos, f"rovers.units[{i}].position"),
            ))
        return rovers
    fl = _mapping(r.get("fleet"), "rovers.fleet")
    count = _int(fl.get("count"), "rovers.fleet.count")
    start = _int(fl.get("sysid_start", carrier.sysid + 1), "rovers.fleet.sysid_start")
    if count < 0 or start + count - 1 > 255:
        raise ConfigError(f"rovers.fleet: sysids {start}..{start + count - 1} do not fit in 1..255")
    return [spec(f"r{k + 1}", start + k) for k in range(count)]


def _faults(sim: Mapping[str, Any]) -> list[Fault]:
    raw_faults = sim.get("faults") or []
    if not isinstance(raw_faults, list):
        raise ConfigError("sim.faults: expected a list")
    faults: list[Fault] = []
    for i, fd in enumerate(raw_faults):
        try:
            faults.append(Fault.from_dict(fd, f"sim.faults[{i}]"))
        except FaultError as exc:
            raise ConfigError(str(exc)) from None
    return faults


def _signing(d: Mapping[str, Any], signing_key: bytes | None, from_env: bool) -> dict[str, Any]:
    links = d.get("links")
    signing = links.get("signing") if isinstance(links, Mapping) else None
    key_env = signing.get("key_env") if isinstance(signing, Mapping) else None
    if signing_key is not None:
        return {"signing_key": bytes(signing_key)}
    if from_env and isinstance(key_env, str):
        try:
            return {"signing_key": key_from_env(key_env)}
        except ValueError as exc:
            raise ConfigError(f"links.signing: {exc}") from None
    return {}


def _positive(val: Any, where: str) -> None:
    if isinstance(val, bool) or not isinstance(val, int | float) or not math.isfinite(val) or val <= 0:
        raise ConfigError(f"{where}: expected a number > 0, got {val!r}")


def _mapping(val: Any, where: str) -> Mapping[str, Any]:
    if not isinstance(val, Mapping):
        raise ConfigError(f"{where}: expected a mapping, got {type(val).__name__}")
    return val


def _num(val: Any, where: str) -> float:
    if isinstance(val, bool) or not isinstance(val, int | float) or not math.isfinite(val):
        raise ConfigError(f"{where}: expected a number, got {val!r}")
    return float(val)


def _pos_num(val: Any, where: str) -> float:
    _positive(val, where)
    return float(val)


def _opt_pos(val: Any, where: str) -> float | None:
    return None if val is None else _pos_num(val, where)


def _int(val: Any, where: str) -> int:
    if isinstance(val, bool) or not isinstance(val, int):
        raise ConfigError(f"{where}: expected an integer, got {val!r}")
    return val


def _position(val: Any, where: str, ground: bool = False) -> tuple[float, float, float]:
    if not isinstance(val, list | tuple) or len(val) not in (2, 3):
        raise ConfigError(f"{where}: expected [x, y] or [x, y, z] in metres")
    x, y = _num(val[0], where), _num(val[1], where)
    z = 0.0 if ground or len(val) == 2 else _num(val[2], where)
    if z < 0:
        raise ConfigError(f"{where}: z must be >= 0 (ground is z = 0)")
    return (x, y, z)
