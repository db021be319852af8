"""A command's effect in the vehicle's own telemetry: on a lossy link the COMMAND_ACK of a command
that was carried out may be lost (each way a packet is lost, a command and its ACK both arrive
only (1 - loss)² of the time: 36 % at 40 % loss), while the vehicle's next report already shows
what the command did. :meth:`fleetctl.mavlink.vehicle.Vehicle.command` ends a command that has
an effect here as soon as a report heard *after it was sent* shows it (resending at the link's
retransmission timeout until the ACK or the effect comes):

==========================  ===================================================================
command                     done when
==========================  ===================================================================
COMPONENT_ARM_DISARM        a HEARTBEAT shows the vehicle armed (param1 = 1) or disarmed (0)
DO_SET_MODE                 a HEARTBEAT shows the mode asked for (:meth:`Vehicle.set_mode`)
MISSION_START               a HEARTBEAT shows the mission mode (only when it was not in it)
NAV_LAND                    a HEARTBEAT shows the landing mode (only when it was not in it)
DO_SET_MISSION_CURRENT      MISSION_CURRENT shows the item, or MISSION_ITEM_REACHED of it, or
                            MISSION_CURRENT past it (:func:`current_taken`)
==========================  ===================================================================

A HEARTBEAT counts only when it was heard after the command was sent (:func:`heartbeat_shows`);
it may have left the vehicle before the command arrived, but then it shows the state the command
asks for already, which the command does not change. Autopilots send their HEARTBEAT at 1 Hz, so
on a real link the effect ends a command whose ACKs keep being lost within about a second; the
simulated fleet sends one at once when its armed state or mode changes (as it sends MISSION_CURRENT
at once when the current item changes)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol

from pymavlink.dialects.v20 import ardupilotmega as M

MISSION_MODE = "MISSION"  # the generic mode a vehicle flies its mission in
LAND_MODE = "LAND"  # the generic mode a vehicle lands in (NAV_LAND switches to it)


class Reports(Protocol):
    """What the effects are read from (:class:`fleetctl.mavlink.vehicle.Vehicle` is one)."""

    heartbeats: int
    armed: bool
    mode: str | None
    mode_firmware: str | None
    mission_current: int | None
    items_reached: set[int]


Effect = Callable[[Any], bool]


def heartbeat_shows(v: Reports, shown: Effect) -> Effect:
    """A predicate on ``v`` that holds once a HEARTBEAT heard from now on satisfies ``shown``."""
    heard = v.heartbeats
    return lambda x: x.heartbeats > heard and shown(x)


def in_mode(mode: str) -> Effect:
    """The vehicle is in ``mode`` (a generic mode or the firmware's own name)."""
    return lambda x: x.mode == mode or x.mode_firmware == mode


def current_taken(v: Reports, seq: int) -> Effect:
    """Item ``seq`` was made current: MISSION_CURRENT shows it, or - when the vehicle stands within
    its acceptance radius and goes straight on, so that ``seq`` is never reported current - it
    reported ``seq`` reached (not reached before) or MISSION_CURRENT past it (from an item before)."""
    before = v.mission_current
    reached = seq in v.items_reached

    def taken(x: Any) -> bool:
        cur = x.mission_current
        if cur == seq or (not reached and seq in x.items_reached):
            return True
        return before is not None and cur is not None and before < seq < cur

    return taken


def effect_of(v: Reports, command: int, params: Sequence[float]) -> Effect | None:
    """The telemetry that shows ``command`` (with ``params``, param1 first) done on ``v``, as
    the table above; None for a command whose effect is not read."""
    if command == M.MAV_CMD_COMPONENT_ARM_DISARM and params:
        want = params[0] >= 0.5
        return heartbeat_shows(v, lambda x: bool(x.armed) == want)
    if command == M.MAV_CMD_MISSION_START and v.mode != MISSION_MODE:
        return heartbeat_shows(v, in_mode(MISSION_MODE))
    if command == M.MAV_CMD_NAV_LAND and v.mode != LAND_MODE:
        return heartbeat_shows(v, in_mode(LAND_MODE))
    if command == M.MAV_CMD_DO_SET_MISSION_CURRENT and params:
        return current_taken(v, int(params[0]))
    return None


__all__ = ["LAND_MODE", "MISSION_MODE", "Effect", "Reports", "current_taken", "effect_of", "heartbeat_shows",
           "in_mode"]
