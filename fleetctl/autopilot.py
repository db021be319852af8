"""What differs between autopilot firmwares (PX4, ArduPilot), behind one small class.

The controller speaks in generic flight modes - ``HOLD``, ``GUIDED``, ``MISSION``, ``TAKEOFF``,
``LAND``, ``RTL``, ``MANUAL`` - and the :class:`Autopilot` chosen from the vehicle's HEARTBEAT
(``Autopilot.from_heartbeat``) maps them to custom-mode numbers, decodes the HEARTBEAT's mode,
and knows how the firmware wants take-off and mission start:

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
from typing import TYPE_CHECKING, Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

if TYPE_CHECKING:
    from fleetctl.vehicle import Vehicle

M = mavlink2
MODES = ("HOLD", "GUIDED", "MISSION", "TAKEOFF", "LAND", "RTL", "MANUAL")
_CUSTOM = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED


class ModeError(ValueError):
    """A flight mode this autopilot does not have."""


class Autopilot:
    """Base class: firmware-independent defaults. Subclasses override the mode tables."""

    name = "generic"
    home_is_item0 = False  # True: mission item 0 is home (ArduPilot)

    def __init__(self, mav_type: int = M.MAV_TYPE_GENERIC) -> None:
        self.mav_type = mav_type

    @staticmethod
    def from_heartbeat(msg: Any) -> Autopilot:
        """The autopilot class for a vehicle's HEARTBEAT (``autopilot`` and ``type`` fields)."""
        if msg.autopilot == M.MAV_AUTOPILOT_PX4:
            return Px4(msg.type)
        if msg.autopilot == M.MAV_AUTOPILOT_ARDUPILOTMEGA:
            return ArduPilot(msg.type)
        return GenericAutopilot(msg.type)

    @property
    def ground(self) -> bool:
        return self.mav_type in (M.MAV_TYPE_GROUND_ROVER, M.MAV_TYPE_SURFACE_BOAT)

    # -- modes -------------------------------------------------------------------------------------
    def firmware_mode(self, base_mode: int, custom_mode: int) -> str:
        """The firmware's own name of the mode in a HEARTBEAT (e.g. ``AUTO.LOITER``, ``GUIDED``)."""
        return _base_mode_name(base_mode)

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


class Px4(Autopilot):
    name = "px4"
    _MAIN = {1: "MANUAL", 2: "ALTCTL", 3: "POSCTL", 4: "AUTO", 5: "ACRO", 6: "OFFBOARD", 7: "STABILIZED",
             8: "RATTITUDE"}
    _AUTO = {1: "READY", 2: "TAKEOFF", 3: "LOITER", 4: "MISSION", 5: "RTL", 6: "LAND", 7: "RTGS",
             8: "FOLLOW_TARGET", 9: "PRECLAND"}
    _GENERIC = {(4, 2): "TAKEOFF", (4, 3): "HOLD", (4, 4): "MISSION", (4, 5): "RTL", (4, 6): "LAND",
                (3, 0): "MANUAL"}
    _SET = {"HOLD": (4, 3), "GUIDED": (4, 3), "MISSION": (4, 4), "TAKEOFF": (4, 2), "LAND": (4, 6),
            "RTL": (4, 5), "MANUAL": (3, 0), "POSCTL": (3, 0), "OFFBOARD": (6, 0)}

    @staticmethod
    def _split(custom_mode: int) -> tuple[int, int]:
        main = (custom_mode >> 16) & 0xFF
        sub = (custom_mode >> 24) & 0xFF
        return main, (sub if main == 4 else 0)

    def firmware_mode(self, base_mode: int, custom_mode: int) -> str:
        if not base_mode & _CUSTOM:
            return _base_mode_name(base_mode)
        main, sub = self._split(custom_mode)
        name = self._MAIN.get(main, f"MAIN{main}")
        return f"{name}.{self._AUTO.get(sub, f'SUB{sub}')}" if main == 4 else name

    def mode_name(self, base_mode: int, custom_mode: int) -> str:
        if base_mode & _CUSTOM:
            generic = self._GENERIC.get(self._split(custom_mode))
            if generic is not None:
                return generic
        return self.firmware_mode(base_mode, custom_mode)

    def set_mode_params(self, mode: str) -> tuple[float, float, float]:
        key = mode.upper()
        if key not in self._SET:
            raise ModeError(f"PX4 has no mode {mode!r}; use one of {', '.join(sorted(self._SET))}")
        main, sub = self._SET[key]
        return float(_CUSTOM), float(main), float(sub)

    async def takeoff(self, vehicle: Vehicle, height: float) -> None:
        home = vehicle.home_amsl
        if home is None:
            raise RuntimeError(f"{vehicle.name}: home altitude unknown (no GLOBAL_POSITION_INT yet)")
        nan = math.nan
        await vehicle.command(M.MAV_CMD_NAV_TAKEOFF, (nan, 0, 0, nan, nan, nan, home + height))

    async def start_mission(self, vehicle: Vehicle, first: int = 0) -> None:
        if first > 0:
            await vehicle.set_current(first)
        await vehicle.set_mode("MISSION")


class ArduPilot(Autopilot):
    name = "ardupilot"
    home_is_item0 = True
    _COPTER = {0: "STABILIZE", 1: "ACRO", 2: "ALT_HOLD", 3: "AUTO", 4: "GUIDED", 5: "LOITER", 6: "RTL",
               7: "CIRCLE", 9: "LAND", 11: "DRIFT", 13: "SPORT", 14: "FLIP", 15: "AUTOTUNE", 16: "POSHOLD",
               17: "BRAKE", 18: "THROW", 19: "AVOID_ADSB", 20: "GUIDED_NOGPS", 21: "SMART_RTL"}
    _ROVER = {0: "MANUAL", 1: "ACRO", 3: "STEERING", 4: "HOLD", 5: "LOITER", 6: "FOLLOW", 7: "SIMPLE",
              10: "AUTO", 11: "RTL", 12: "SMART_RTL", 15: "GUIDED"}
    _COPTER_GENERIC = {"HOLD": 5, "GUIDED": 4, "MISSION": 3, "TAKEOFF": 4, "LAND": 9, "RTL": 6, "MANUAL": 5}
    _ROVER_GENERIC = {"HOLD": 4, "GUIDED": 15, "MISSION": 10, "LAND": 4, "RTL": 11, "MANUAL": 0}
    _REPORT = {"AUTO": "MISSION", "LOITER": "HOLD", "BRAKE": "HOLD", "POSHOLD": "HOLD"}

    def _table(self) -> dict[int, str]:
        return self._ROVER if self.ground else self._COPTER

    def firmware_mode(self, base_mode: int, custom_mode: int) -> str:
        if not base_mode & _CUSTOM:
            return _base_mode_name(base_mode)
        return self._table().get(custom_mode, f"MODE{custom_mode}")

    def mode_name(self, base_mode: int, custom_mode: int) -> str:
        fw = self.firmware_mode(base_mode, custom_mode)
        if self.ground and fw == "LOITER":
            return "HOLD"
        return self._REPORT.get(fw, fw)

    def set_mode_params(self, mode: str) -> tuple[float, float, float]:
        key = mode.upper()
        generic = self._ROVER_GENERIC if self.ground else self._COPTER_GENERIC
        if key in generic:
            return float(_CUSTOM), float(generic[key]), 0.0
        for num, name in self._table().items():
            if name == key:
                return float(_CUSTOM), float(num), 0.0
        raise ModeError(f"ArduPilot has no mode {mode!r}; use one of {', '.join(sorted(generic))}")

    async def takeoff(self, vehicle: Vehicle, height: float) -> None:
        if self.ground:
            raise ModeError(f"{vehicle.name}: a ground vehicle cannot take off")
        if vehicle.mode != "GUIDED":
            await vehicle.set_mode("GUIDED")
        await vehicle.command(M.MAV_CMD_NAV_TAKEOFF, (0, 0, 0, 0, 0, 0, height))

    async def start_mission(self, vehicle: Vehicle, first: int = 0) -> None:
        await vehicle.set_mode("MISSION")
        await vehicle.command(M.MAV_CMD_MISSION_START, (max(first, 0), 0))


class GenericAutopilot(Autopilot):
    name = "generic"


def _base_mode_name(base_mode: int) -> str:
    if base_mode & M.MAV_MODE_FLAG_AUTO_ENABLED:
        return "AUTO"
    if base_mode & M.MAV_MODE_FLAG_GUIDED_ENABLED:
        return "GUIDED"
    if base_mode & M.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED:
        return "MANUAL"
    return "UNKNOWN"


__all__ = ["MODES", "ArduPilot", "Autopilot", "GenericAutopilot", "ModeError", "Px4"]
