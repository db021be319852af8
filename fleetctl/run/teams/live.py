"""What a run of several teams reads from the live fleet to share the work: the mission with
every carrier where its telemetry puts it, and the launched rovers waiting in the field with the
range their batteries leave them (a ``run``'s collection)."""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Iterable

from fleetctl.mavlink.fleet import Fleet
from fleetctl.mavlink.link import LinkError
from fleetctl.mission import Mission
from fleetctl.mission.flight import MEET_HEIGHT
from fleetctl.mission.teams import mission_teams
from fleetctl.run.energy import range_from_percent
from fleetctl.run.state import on_deck
from planners.core.problem import CollectRover


def live_mission(mission: Mission, fleet: Fleet | None) -> Mission:
    """``mission`` with every carrier at its live position and heading (the mission's where
    telemetry has none)."""
    teams = []
    for t in mission_teams(mission):
        v = fleet.vehicles.get(t.carrier.id) if fleet is not None else None
        c = t.carrier
        if v is not None and v.enu is not None:
            c = dataclasses.replace(c, position=(v.enu[0], v.enu[1]))
        if v is not None and v.heading_deg is not None:
            c = dataclasses.replace(c, heading_deg=v.heading_deg)
        teams.append(dataclasses.replace(t, carrier=c))
    return dataclasses.replace(mission, teams=tuple(teams), carrier=teams[0].carrier)


async def rovers_in_the_field(
    mission: Mission, fleet: Fleet, launched: Iterable[str], left: dict[str, str]
) -> tuple[CollectRover, ...]:
    """Every ``launched`` rover not on a deck now, with its live position and fresh range. One
    without a position, or without the range to reach the approach height above it, goes to
    ``left`` (rover -> why) instead."""
    rp = mission.rovers
    carriers = [(fleet.vehicles[t.carrier.id].enu, t.carrier.deck_height) for t in mission_teams(mission)]
    out = []
    for rid in dict.fromkeys(launched):
        v = fleet.vehicles[rid]
        if not v.connected or v.lost or v.enu is None:
            left[rid] = "lost: no position to collect it from"
            continue
        if any(on_deck(v.enu, c, v.on_ground, v.ground_speed, v.height, deck) for c, deck in carriers):
            continue
        with contextlib.suppress(LinkError, TimeoutError):
            await v.refresh_battery()
        rng = range_from_percent(v.battery_pct, rp.reserve, rp.endurance_range)
        rng = (1.0 - rp.reserve) * rp.endurance_range if rng is None else rng
        if rng <= 0.0 or rng < abs(max(v.enu[2], 0.0) - MEET_HEIGHT):  # not even to the approach height
            pct = "?" if v.battery_pct is None else f"{v.battery_pct:g}"
            left[rid] = f"unreachable: {rng:.1f} m of range left at {v.enu[2]:.1f} m up (battery {pct} %)"
            continue
        out.append(CollectRover(rid, (v.enu[0], v.enu[1], max(v.enu[2], 0.0)), rng))
    return tuple(out)


__all__ = ["live_mission", "rovers_in_the_field"]
