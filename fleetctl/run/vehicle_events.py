"""What the controller tells of a vehicle's own events (its link lost or back, its text messages,
a geofence breach, arming, mode and landed-state changes): one wording for every run, one team's
(:class:`fleetctl.run.executor.Executor`) or the rovers several teams leave on task while they dwell
(:class:`fleetctl.run.teams.coordinator.TeamsRun`)."""

from __future__ import annotations

from collections.abc import Callable

from fleetctl.mavlink.vehicle import VehicleEvent
from fleetctl.run.kinds import Ev

Tell = Callable[..., object]  # tell(kind, text, vehicle, **data): an event shown and journalled
Record = Callable[..., object]  # record(kind, **data): journalled only


def tell_vehicle_event(ev: VehicleEvent, tell: Tell, record: Record) -> None:
    """Tell ``ev``: link lost/back and geofence breaches as events, the rest journalled."""
    if ev.kind == "lost":
        tell(Ev.LINK_LOST, f"{ev.vehicle}: link lost (nothing heard for {ev.data.get('timeout', 0):g} s)",
             ev.vehicle)
    elif ev.kind == "back":
        tell(Ev.LINK_BACK, f"{ev.vehicle}: link back", ev.vehicle)
    elif ev.kind == "statustext":
        record(Ev.STATUSTEXT, vehicle=ev.vehicle, text=ev.data.get("text"), severity=ev.data.get("severity"))
    elif ev.kind == "geofence_breach":
        tell(Ev.GEOFENCE_BREACH, f"{ev.vehicle}: geofence breach ({ev.data.get('breach', '?')}); "
             f"its autopilot does the geofence action", ev.vehicle, **ev.data)
    elif ev.kind in ("armed", "disarmed", "mode", "landed_state"):
        record(ev.kind, vehicle=ev.vehicle, **ev.data)


def battery_low_text(rover: str, pct: float) -> str:
    return f"{rover}: battery {pct}% at or below the reserve the plan assumed"


__all__ = ["battery_low_text", "tell_vehicle_event"]
