"""The embedded simulated fleet of a run: the mission dict it is started from."""

from __future__ import annotations

import copy
from typing import Any

from fleetctl.mission import Mission
from fleetctl.run.context import ExecutionError


def sim_mission_dict(mission: Mission, command: str = "deploy") -> dict[str, Any]:
    """The mission dict the embedded simulator is started from: the file as written, with the
    rover units spelled out (the file may leave them to defaults). For ``collect`` the rovers
    named in the mission's ``collection`` section start in the field at their positions (the
    others on the deck); without that section a collection on the simulator is refused."""
    d = copy.deepcopy(mission.raw)
    if "carriers" in d:  # one team written as 'carriers: [...]' (several teams do not fly yet)
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


def mission_uses_sim(mission: Mission) -> bool:
    return mission.carrier.connection == "sim" or any(u.connection == "sim" for u in mission.rovers.units)


__all__ = ["mission_uses_sim", "sim_mission_dict"]
