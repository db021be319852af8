"""ArduPilot (Copter and Rover): mode numbers, GUIDED take-off, mission item 0 = home."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from fleetctl.mavlink.autopilots.base import CUSTOM, Autopilot, ModeError, Vehicle, base_mode_name

M = mavlink2


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
        if not base_mode & CUSTOM:
            return base_mode_name(base_mode)
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
            return float(CUSTOM), float(generic[key]), 0.0
        for num, name in self._table().items():
            if name == key:
                return float(CUSTOM), float(num), 0.0
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
