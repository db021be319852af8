"""Firmware differences behind one small class per autopilot (:mod:`.base` documents the table).

To add a flavour: subclass :class:`~fleetctl.mavlink.autopilots.base.Autopilot` in a module of its
own here and return it from :func:`autopilot_for` for its ``MAV_AUTOPILOT`` value."""

from __future__ import annotations

from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from fleetctl.mavlink.autopilots.ardupilot import ArduPilot
from fleetctl.mavlink.autopilots.base import MODES, Autopilot, ModeError
from fleetctl.mavlink.autopilots.generic import GenericAutopilot
from fleetctl.mavlink.autopilots.px4 import Px4


def autopilot_for(heartbeat: Any) -> Autopilot:
    """The autopilot class for a vehicle's HEARTBEAT (``autopilot`` and ``type`` fields)."""
    if heartbeat.autopilot == mavlink2.MAV_AUTOPILOT_PX4:
        return Px4(heartbeat.type)
    if heartbeat.autopilot == mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA:
        return ArduPilot(heartbeat.type)
    return GenericAutopilot(heartbeat.type)


__all__ = ["MODES", "ArduPilot", "Autopilot", "GenericAutopilot", "ModeError", "Px4", "autopilot_for"]
