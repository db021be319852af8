"""What differs between autopilot firmwares (PX4, ArduPilot), behind one small class.

The controller speaks in generic flight modes - ``HOLD``, ``GUIDED``, ``MISSION``, ``TAKEOFF``,
``LAND``, ``RTL``, ``MANUAL`` - and the :class:`Autopilot` chosen from the vehicle's HEARTBEAT
(:func:`fleetctl.mavlink.autopilots.autopilot_for`) maps them to custom-mode numbers, decodes
the HEARTBEAT's mode, and knows how the firmware wants take-off and mission start:

=============  ==========================================  =========================================
               PX4                                         ArduPilot
=============  ==========================================  =========================================
modes          custom_mode = main << 16 | sub << 24        Copter / Rover mode numbers
               (AUTO = 4: LOITER 3, MISSION 4, RTL 5, ...)  (Copter AUTO 3, GUIDED 4, LOITER 5, ...)
take-off       NAV_TAKEOFF, param7 = AMSL altitude,        GUIDED, then NAV_TAKEOFF with param7 =
               other params NaN                            height above home, other params 0
mission start  DO_SET_MODE(AUTO.MISSION)                   DO_SET_MODE(AUTO), then MISSION_START
mission item 0 the first item                              home (written by the vehicle)
=============  ==========================================  =========================================

Other autopilots get :class:`GenericAutopilot`: standard commands only (MISSION_START,
NAV_TAKEOFF, NAV_LAND, NAV_RETURN_TO_LAUNCH); setting a custom mode raises :class:`ModeError`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any, Protocol

from pymavlink.dialects.v20 import ardupilotmega as mavlink2


class Vehicle(Protocol):
    """What an autopilot needs of a vehicle (:class:`fleetctl.mavlink.vehicle.Vehicle` is one)."""

    name: str
    mode: str | None

    @property
    def home_amsl(self) -> float | None: ...

    async def command(self, command: int, params: Iterable[float] = (), *, frame: int | None = None,
                      check: bool = True, timeout: float | None = None) -> Any: ...

    async def set_mode(self, mode: str) -> None: ...

    async def set_current(self, seq: int) -> None: ...

M = mavlink2
MODES = ("HOLD", "GUIDED", "MISSION", "TAKEOFF", "LAND", "RTL", "MANUAL")
CUSTOM = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED


class ModeError(ValueError):
    """A flight mode this autopilot does not have."""


class Autopilot:
    """Base class: firmware-independent defaults. Subclasses override the mode tables."""

    name = "generic"
    home_is_item0 = False  # True: mission item 0 is home (ArduPilot)

    def __init__(self, mav_type: int = M.MAV_TYPE_GENERIC) -> None:
        self.mav_type = mav_type

    @property
    def ground(self) -> bool:
        return self.mav_type in (M.MAV_TYPE_GROUND_ROVER, M.MAV_TYPE_SURFACE_BOAT)

    # -- modes -------------------------------------------------------------------------------------
    def firmware_mode(self, base_mode: int, custom_mode: int) -> str:
        """The firmware's own name of the mode in a HEARTBEAT (e.g. ``AUTO.LOITER``, ``GUIDED``)."""
        return base_mode_name(base_mode)

    def mode_name(self, base_mode: int, custom_mode: int) -> str:
        """The generic mode (one of :data:`MODES`) of a HEARTBEAT, else the firmware's name."""
        return self.firmware_mode(base_mode, custom_mode)

    def set_mode_params(self, mode: str) -> tuple[float, float, float]:
        """DO_SET_MODE param1..param3 for a generic mode (or a firmware mode name)."""
        raise ModeError(f"{self.name} autopilot: cannot set mode {mode!r} (custom modes unknown)")

    # -- firmware-specific sequences ------------------------------------------------------------------
    async def takeoff(self, vehicle: Vehicle, height: float) -> None:
        """Take off to ``height`` metres above home (the vehicle must be armed)."""
        await vehicle.command(M.MAV_CMD_NAV_TAKEOFF, (0, 0, 0, math.nan, 0, 0, height))

    async def start_mission(self, vehicle: Vehicle, first: int = 0) -> None:
        """Fly the uploaded mission from its current item (or ``first`` if > 0)."""
        await vehicle.command(M.MAV_CMD_MISSION_START, (first, 0))


def base_mode_name(base_mode: int) -> str:
    if base_mode & M.MAV_MODE_FLAG_AUTO_ENABLED:
        return "AUTO"
    if base_mode & M.MAV_MODE_FLAG_GUIDED_ENABLED:
        return "GUIDED"
    if base_mode & M.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED:
        return "MANUAL"
    return "UNKNOWN"



__all__ = ["CUSTOM", "MODES", "Autopilot", "ModeError", "Vehicle", "base_mode_name"]
