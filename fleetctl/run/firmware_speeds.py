"""The mission's speeds on the autopilots, and the time model's handling terms fitted to them.

With ``carrier.firmware_speeds`` / ``rovers.firmware_speeds`` ``set`` (the default on real links)
the preflight writes the speeds the plan assumes into each autopilot's own parameters (the table
of :meth:`fleetctl.mavlink.autopilots.base.Autopilot.speed_params`: ArduCopter ``WPNAV_SPEED``,
``WPNAV_ACCEL``, ``WPNAV_SPEED_UP``, ``WPNAV_SPEED_DN``, ``LAND_SPEED``; ArduRover ``WP_SPEED``,
``CRUISE_SPEED``, ``WP_ACCEL``, ``ATC_ACCEL_MAX``; PX4 ``MPC_*``), each clamped to the range the
firmware flies safely, and reads them back. A parameter the firmware does not have is skipped.

The rovers' take-off clearance and touch-down (``rovers.takeoff_time``, ``rovers.land_time``)
that the mission does not give are then taken from the autopilot's measured handling
(:meth:`~fleetctl.mavlink.autopilots.base.Autopilot.handling_times`), so that the plan predicts
the firmware. ``keep`` leaves the autopilots' parameters and the mission's times as they are.
docs/autopilots.md lists the parameters and the measurements.
"""

from __future__ import annotations

import asyncio
import dataclasses
from dataclasses import dataclass, field

from fleetctl.mavlink.autopilots import Autopilot
from fleetctl.mavlink.fleet import Fleet
from fleetctl.mavlink.params import ParamError, read_params, set_param
from fleetctl.mavlink.vehicle import Vehicle
from fleetctl.mission import Mission


@dataclass
class SpeedsReport:
    """What the preflight wrote: vehicle -> {parameter: value}; the mission to plan with."""

    written: dict[str, dict[str, float]] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)  # vehicle -> why its speeds are not set
    mission: Mission | None = None  # with the fitted take-off / touch-down times, when they changed


def quantities(mission: Mission, carrier: bool) -> dict[str, float | None]:
    """The mission's speeds of a role, by the names :class:`SpeedParam` uses."""
    if carrier:
        c = mission.carrier
        return {"max_speed": c.max_speed, "accel": c.accel, "climb_rate": None, "land_speed": None}
    r = mission.rovers
    return {"max_speed": r.max_speed, "accel": r.accel, "climb_rate": r.climb_rate,
            "land_speed": r.land_speed}


async def write_speeds(v: Vehicle, values: dict[str, float]) -> dict[str, float]:
    """Set the parameters the vehicle has (read first: unknown names are skipped); returns what
    was written, as read back."""
    present = await read_params(v, list(values), timeout=0.5, retries=2)
    out: dict[str, float] = {}
    for name, value in values.items():
        if present.get(name) is None:
            continue
        out[name] = await set_param(v, name, value)
    return out


async def apply_firmware_speeds(fleet: Fleet, mission: Mission, vehicles: list[str]) -> SpeedsReport:
    """Write the mission's speeds to ``vehicles`` (those whose role says ``set``) and fit the
    rovers' handling times (see the module docstring)."""
    rep = SpeedsReport()
    todo: dict[str, dict[str, float]] = {}
    for vid in vehicles:
        v = fleet.vehicles[vid]
        carrier = vid == fleet.carrier_id
        mode = mission.carrier.firmware_speeds if carrier else mission.rovers.firmware_speeds
        if mode != "set" or v.autopilot is None:
            continue
        values = v.autopilot.speed_values(quantities(mission, carrier))
        if values:
            todo[vid] = values

    async def one(vid: str) -> None:
        try:
            rep.written[vid] = await write_speeds(fleet.vehicles[vid], todo[vid])
        except (ParamError, TimeoutError) as exc:
            rep.failed[vid] = str(exc)

    await asyncio.gather(*(one(vid) for vid in todo))
    rover_aps = [fleet.vehicles[vid].autopilot for vid in rep.written if vid != fleet.carrier_id]
    carrier_ap = fleet.vehicles[fleet.carrier_id].autopilot if fleet.carrier_id in rep.written else None
    rep.mission = fitted_handling(mission, [ap for ap in rover_aps if ap is not None], carrier_ap)
    return rep


def fitted_handling(mission: Mission, autopilots: list[Autopilot],
                    carrier: Autopilot | None = None) -> Mission | None:
    """The mission with the rovers' take-off and touch-down times and leg acceleration of their
    firmware (the slowest of ``autopilots``), the times where the mission file does not give them,
    and the carrier's leg acceleration and turn rate as its ``carrier`` firmware drives; None when
    nothing changes."""
    out = mission
    r = mission.rovers
    load, deck = mission.carrier.load_time, mission.carrier.deck_height
    fits = [t for ap in autopilots
            if (t := ap.handling_times(r.climb_rate, r.land_speed, load, deck)) is not None]
    if fits:
        takeoff_given, land_given = r.handling_given
        takeoff = r.takeoff_time if takeoff_given else max(t for t, _ in fits)
        land = r.land_time if land_given else max(t for _, t in fits)
        accels = [a for ap in autopilots if (a := ap.planned_accel(r.max_speed, r.accel)) is not None]
        accel = min(accels) if accels and r.accel is not None else r.accel
        fitted = dataclasses.replace(r, takeoff_time=takeoff, land_time=land, accel=accel)
        out = dataclasses.replace(out, rovers=fitted)
    c = mission.carrier
    if carrier is not None:
        c_accel = carrier.planned_accel(c.max_speed, c.accel)
        turn = carrier.planned_turn_rate(c.turn_rate)
        out = dataclasses.replace(out, carrier=dataclasses.replace(c, accel=c_accel, turn_rate=turn))
    return None if out == mission else out


__all__ = ["SpeedsReport", "apply_firmware_speeds", "fitted_handling", "quantities", "write_speeds"]
