"""What the controller tells of a vehicle's own events (its link lost or back, its text messages,
a geofence breach, arming, mode and landed-state changes): one wording for every run, one team's
(:class:`fleetctl.run.executor.Executor`) or the rovers several teams leave on task while they dwell
(:class:`fleetctl.run.teams.coordinator.TeamsFlight`)."""

from __future__ import annotations

from collections.abc import Callable

from fleetctl.mavlink.vehicle import VehicleEvent, VehicleEventKind
from fleetctl.run.kinds import Ev

Tell = Callable[..., object]  # tell(kind, text, vehicle, **data): an event shown and journalled
Record = Callable[..., object]  # record(kind, **data): journalled only
# the vehicle events journalled under the same name, with the vehicle and the event's data
JOURNALLED = {VehicleEventKind.ARMED: Ev.ARMED, VehicleEventKind.DISARMED: Ev.DISARMED,
              VehicleEventKind.MODE: Ev.MODE, VehicleEventKind.LANDED_STATE: Ev.LANDED_STATE}


def tell_vehicle_event(ev: VehicleEvent, tell: Tell, record: Record) -> None:
    """Tell ``ev``: link lost/back and geofence breaches as events, the rest journalled."""
    if ev.kind == VehicleEventKind.LOST:
        tell(Ev.LINK_LOST, f"{ev.vehicle}: link lost (nothing heard for {ev.data.get('timeout', 0):g} s)",
             ev.vehicle)
    elif ev.kind == VehicleEventKind.BACK:
        tell(Ev.LINK_BACK, f"{ev.vehicle}: link back", ev.vehicle)
    elif ev.kind == VehicleEventKind.STATUSTEXT:
        record(Ev.STATUSTEXT, vehicle=ev.vehicle, text=ev.data.get("text"), severity=ev.data.get("severity"))
    elif ev.kind == VehicleEventKind.GEOFENCE_BREACH:
        tell(Ev.GEOFENCE_BREACH, f"{ev.vehicle}: geofence breach ({ev.data.get('breach', '?')}); "
             f"its autopilot does the geofence action", ev.vehicle, **ev.data)
    elif (kind := JOURNALLED.get(ev.kind)) is not None:
        record(kind, vehicle=ev.vehicle, **ev.data)


def battery_low_text(rover: str, pct: float) -> str:
    return f"{rover}: battery {pct}% at or below the reserve the plan assumed"


__all__ = ["battery_low_text", "tell_vehicle_event"]
