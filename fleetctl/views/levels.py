"""Warning levels the views colour by (terminal and web map alike).

Battery: below the mission's reserve ``reserve`` (red), below twice the reserve ``low`` (yellow),
else ``ok``. Link: ``lost`` (red) once the vehicle is declared lost, ``stale`` (yellow) after
:data:`STALE_LINK` s without a message, else ``ok``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fleetctl.run.state import FleetState, VehicleState

STALE_LINK = 2.0  # s without a message: the link is shown as stale


def battery_level(state: FleetState, v: VehicleState) -> str:
    """``reserve`` | ``low`` | ``ok`` | ``unknown`` for ``v``'s battery against the mission's reserve."""
    if v.battery_pct is None:
        return "unknown"
    reserve = state.reserve * 100.0
    if v.battery_pct < reserve:
        return "reserve"
    if v.battery_pct < 2.0 * reserve:
        return "low"
    return "ok"


def link_level(v: VehicleState) -> str:
    """``lost`` | ``stale`` | ``ok`` | ``unknown``."""
    if v.lost:
        return "lost"
    if v.link_age is None:
        return "unknown"
    return "stale" if v.link_age > STALE_LINK else "ok"


STYLE = {"reserve": "bold red", "low": "yellow", "lost": "bold red", "stale": "yellow"}

__all__ = ["STALE_LINK", "STYLE", "battery_level", "link_level"]
