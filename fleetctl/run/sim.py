"""The embedded simulated fleet of a run: its typed configuration, built from the typed mission
(:func:`sim_fleet_config`: every carrier and rover of every team), the one way every command starts
and stops it (:func:`embedded_fleet`: the runs, ``status``, ``keys provision`` and ``sim``), and the
mission dict older callers start ``sitl`` from (:func:`sim_mission_dict`, one team)."""

from __future__ import annotations

import copy
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import TYPE_CHECKING, Any

from fleetctl.mission import Mission
from fleetctl.mission.model import CarrierConfig, Fault
from fleetctl.mission.teams import mission_teams
from fleetctl.run.context import ExecutionError

if TYPE_CHECKING:
    from sitl import FleetConfig, SimFleet, VehicleSpec


def sim_fleet_config(mission: Mission, command: str = "deploy", *, speedup: float | None = None,
                     signing_from_env: bool = True) -> FleetConfig:
    """The simulated fleet of ``mission`` from its validated keys (no second reading of the file):
    every carrier of every team at its start, each rover on its own carrier's deck sharing that
    carrier's link unless it has a connection of its own. ``collect``: the rovers of the
    ``collection:`` section start in the field (see :func:`sim_mission_dict` for the refusal
    without one). ``speedup`` overrides ``sim.speedup``. A bad signing key variable is an
    :class:`ExecutionError`."""
    from sitl import ConfigError, FleetConfig
    from sitl.signing import key_from_env

    placed = _placed(mission, command)
    carriers = [_carrier_spec(t.carrier) for t in mission_teams(mission)]
    teams = mission_teams(mission)
    home = {rid: t.carrier.id for t in teams for rid in t.rovers} if len(teams) > 1 else {}
    rovers = [_rover_spec(mission, u.id, u.sysid, u.connection, placed.get(u.id), home.get(u.id))
              for u in mission.rovers.units]
    key = None
    if signing_from_env and mission.links.signing is not None:
        try:
            key = key_from_env(mission.links.signing.key_env)
        except ValueError as exc:
            raise ExecutionError(f"links.signing: {exc}") from None
    o = mission.origin
    assert o is not None  # _placed refused a mission without one
    try:
        return FleetConfig(origin=(o.lat, o.lon, o.alt), carrier=carriers[0], rovers=rovers,
                           more_carriers=carriers[1:],
                           speedup=speedup if speedup is not None else mission.sim.speedup,
                           seed=mission.planner.seed, faults=[_fault(f) for f in mission.sim.faults],
                           name=mission.name, signing_key=key)
    except ConfigError as exc:
        raise ExecutionError(f"{mission.path or mission.name}: {exc}") from None


def _placed(mission: Mission, command: str) -> dict[str, tuple[float, float, float]]:
    if mission.origin is None:
        raise ExecutionError(
            f"{mission.path or mission.name}: the mission has no origin; flying needs "
            "WGS84 coordinates: add origin: {lat, lon, alt} to the mission file"
        )
    if command != "collect":
        return {}
    if not mission.collection:
        raise ExecutionError(
            f"{mission.path or mission.name}: 'collect' on the simulated fleet needs a 'collection:' "
            "section (where the rovers are); the simulated rovers otherwise start on the carrier's "
            "deck. Add one, or fly 'fleetctl run' (deploy, dwell, collect)"
        )
    return {r.id: (float(r.position[0]), float(r.position[1]), float(r.position[2]))
            for r in mission.collection}


def _carrier_spec(c: CarrierConfig) -> VehicleSpec:
    from sitl import VehicleSpec

    return VehicleSpec(id=c.id, sysid=c.sysid, role="carrier", max_speed=c.max_speed, accel=c.accel,
                       connection=c.connection, position=(c.position[0], c.position[1], 0.0),
                       heading_deg=c.heading_deg, turn_rate=c.turn_rate, frame="ground")


def _rover_spec(mission: Mission, rid: str, sysid: int, connection: str | None,
                position: tuple[float, float, float] | None, carrier: str | None) -> VehicleSpec:
    from sitl import VehicleSpec

    rp = mission.rovers
    raw = mission.raw.get("rovers")
    # the simulated battery drains only with an endurance_range written in the file (a derived one
    # is the planners' assumption, not the simulated aircraft's)
    given = isinstance(raw, dict) and raw.get("endurance_range") is not None
    return VehicleSpec(id=rid, sysid=sysid, role="rover", max_speed=rp.max_speed, accel=rp.accel,
                       connection=connection, position=position, climb_rate=rp.climb_rate,
                       land_speed=rp.land_speed, endurance_range=rp.endurance_range if given else None,
                       carrier=carrier)


def _fault(f: Fault) -> Any:
    from sitl import Fault as SimFault

    extra = {k: float(v) for k, v in (("rate", f.rate), ("seconds", f.seconds), ("factor", f.factor),
                                      ("level", f.level), ("distance", f.distance)) if v is not None}
    return SimFault(f.kind, vehicle=f.vehicle, at=f.at, until=f.until, **extra)


def sim_mission_dict(mission: Mission, command: str = "deploy") -> dict[str, Any]:
    """The mission dict the embedded simulator is started from: the file as written, with the
    rover units spelled out (the file may leave them to defaults). For ``collect`` the rovers
    named in the mission's ``collection`` section start in the field at their positions (the
    others on the deck); without that section a collection on the simulator is refused."""
    if len(mission_teams(mission)) > 1:
        raise ExecutionError(f"{mission.path or mission.name}: several carriers: build the simulated fleet "
                             "with sim_fleet_config (every team)")
    d = copy.deepcopy(mission.raw)
    if "carriers" in d:  # one team written as 'carriers: [...]'
        d["carrier"] = {k: v for k, v in d.pop("carriers")[0].items() if k not in ("fleet", "units")}
    if mission.origin is None:
        raise ExecutionError(
            f"{mission.path or mission.name}: the mission has no origin; flying needs "
            "WGS84 coordinates: add origin: {lat, lon, alt} to the mission file"
        )
    placed: dict[str, Any] = {}
    if command == "collect":
        if not mission.collection:
            raise ExecutionError(
                f"{mission.path or mission.name}: 'collect' on the simulated fleet needs a 'collection:' "
                "section (where the rovers are); the simulated rovers otherwise start on the carrier's "
                "deck. Add one, or fly 'fleetctl run' (deploy, dwell, collect)"
            )
        placed = {r.id: r.position for r in mission.collection}
    units = []
    for u in mission.rovers.units:
        unit: dict[str, Any] = {"id": u.id, "sysid": u.sysid}
        if u.connection is not None:
            unit["connection"] = u.connection
        if u.id in placed:
            unit["position"] = [float(c) for c in placed[u.id]]
        units.append(unit)
    rovers = dict(d["rovers"])
    rovers.pop("fleet", None)
    rovers["units"] = units
    d["rovers"] = rovers
    c = dict(d["carrier"])
    c.setdefault("id", mission.carrier.id)
    c.setdefault("sysid", mission.carrier.sysid)
    c["connection"] = mission.carrier.connection  # in fleetctl's spelling (docs/mavlink.md)
    d["carrier"] = c
    return d


@asynccontextmanager
async def embedded_fleet(mission: Mission, command: str = "deploy", *, speedup: float | None = None,
                         signing_from_env: bool = True, config: FleetConfig | None = None,
                         always: bool = False) -> AsyncIterator[SimFleet | None]:
    """``async with embedded_fleet(mission) as sim:`` - the simulated fleet of a ``connection: sim``
    mission running for the block (``None`` for a mission flown on real links), stopped after it.
    ``config``: one already built by :func:`sim_fleet_config`; ``always``: whatever the connections
    say (``fleetctl sim`` serves the mission's own URLs). Its errors (a bad configuration, a
    port in use) are :class:`ExecutionError`."""
    if config is None and not always and not mission_uses_sim(mission):
        yield None
        return
    from sitl import ConfigError, SimFleet
    from sitl import LinkError as SimLinkError

    if config is None:
        config = sim_fleet_config(mission, command, speedup=speedup, signing_from_env=signing_from_env)
    try:
        sim = SimFleet(config)
        await sim.start()
    except (ConfigError, SimLinkError, OSError) as exc:
        raise ExecutionError(f"the simulated fleet cannot start: {exc}") from None
    try:
        yield sim
    finally:
        await sim.stop()


def mission_uses_sim(mission: Mission) -> bool:
    return mission.carrier.connection == "sim" or any(u.connection == "sim" for u in mission.rovers.units)


__all__ = ["embedded_fleet", "mission_uses_sim", "sim_fleet_config", "sim_mission_dict"]
