"""Autopilot flavours (PX4, ArduPilot): HEARTBEAT identity, flight-mode numbers, parameters.

The simulated autopilot has one set of internal modes; a flavour maps them to and from the
custom-mode numbers that firmware reports in HEARTBEAT and accepts in DO_SET_MODE / SET_MODE.
"""

from __future__ import annotations

from enum import Enum

from pymavlink.dialects.v20 import ardupilotmega as mavlink2


class Mode(Enum):
    MANUAL = "manual"  # position hold with no autonomy (PX4 POSCTL, ArduCopter LOITER/STABILIZE)
    HOLD = "hold"  # stop and hold position
    GUIDED = "guided"  # go to a DO_REPOSITION target, then hold
    TAKEOFF = "takeoff"
    MISSION = "mission"
    RTL = "rtl"
    LAND = "land"


# PX4: custom_mode = main_mode << 16 | sub_mode << 24
_PX4_MAIN = {"MANUAL": 1, "ALTCTL": 2, "POSCTL": 3, "AUTO": 4, "ACRO": 5, "OFFBOARD": 6, "STABILIZED": 7}
_PX4_AUTO = {"READY": 1, "TAKEOFF": 2, "LOITER": 3, "MISSION": 4, "RTL": 5, "LAND": 6}
_PX4_REPORT: dict[Mode, tuple[int, int]] = {
    Mode.MANUAL: (_PX4_MAIN["POSCTL"], 0),
    Mode.HOLD: (4, _PX4_AUTO["LOITER"]),
    Mode.GUIDED: (4, _PX4_AUTO["LOITER"]),  # PX4 flies DO_REPOSITION in Hold
    Mode.TAKEOFF: (4, _PX4_AUTO["TAKEOFF"]),
    Mode.MISSION: (4, _PX4_AUTO["MISSION"]),
    Mode.RTL: (4, _PX4_AUTO["RTL"]),
    Mode.LAND: (4, _PX4_AUTO["LAND"]),
}
_PX4_ACCEPT: dict[tuple[int, int], Mode] = {
    (1, 0): Mode.MANUAL, (2, 0): Mode.MANUAL, (3, 0): Mode.MANUAL, (7, 0): Mode.MANUAL,
    (4, 1): Mode.HOLD, (4, 2): Mode.TAKEOFF, (4, 3): Mode.HOLD, (4, 4): Mode.MISSION,
    (4, 5): Mode.RTL, (4, 6): Mode.LAND,
}

# ArduCopter (rovers, multirotor carrier) and ArduRover (ground carrier) mode numbers
_COPTER_REPORT = {Mode.MANUAL: 5, Mode.HOLD: 5, Mode.GUIDED: 4, Mode.TAKEOFF: 4, Mode.MISSION: 3,
                  Mode.RTL: 6, Mode.LAND: 9}
_COPTER_ACCEPT = {0: Mode.MANUAL, 2: Mode.MANUAL, 5: Mode.HOLD, 17: Mode.HOLD, 4: Mode.GUIDED,
                  3: Mode.MISSION, 6: Mode.RTL, 21: Mode.RTL, 9: Mode.LAND}
_ROVER_REPORT = {Mode.MANUAL: 0, Mode.HOLD: 4, Mode.GUIDED: 15, Mode.TAKEOFF: 4, Mode.MISSION: 10,
                 Mode.RTL: 11, Mode.LAND: 4}
_ROVER_ACCEPT = {0: Mode.MANUAL, 4: Mode.HOLD, 5: Mode.HOLD, 15: Mode.GUIDED, 10: Mode.MISSION,
                 11: Mode.RTL, 12: Mode.RTL}

# Parameters a ground station sets, with defaults. All REAL32 (no PX4 int encoding needed).
PX4_PARAMS = {
    "MIS_TAKEOFF_ALT": 2.5,  # m, takeoff height when the command gives none
    "RTL_RETURN_ALT": 0.0,  # m, minimum RTL height (0 = the current height)
    "MPC_XY_CRUISE": 0.0,  # m/s, 0 = the vehicle's max speed
    "MPC_XY_VEL_MAX": 0.0,  # m/s, 0 = the vehicle's max speed
    "NAV_ACC_RAD": 0.5,  # m, waypoint acceptance radius (the sim reaches waypoints exactly)
    "COM_DISARM_LAND": 2.0,  # s after touchdown until auto-disarm, < 0 = never
    "MIS_DIST_1WP": 0.0,
}
ARDUPILOT_PARAMS = {
    "PILOT_TKOFF_ALT": 250.0,  # cm
    "RTL_ALT": 0.0,  # cm, 0 = the current height
    "WPNAV_SPEED": 0.0,  # cm/s, 0 = the vehicle's max speed
    "WP_RADIUS": 0.5,
    "DISARM_DELAY": 2.0,  # s after touchdown until auto-disarm
}


class Flavour:
    """What differs between PX4 and ArduPilot for one vehicle."""

    def __init__(self, autopilot: str, ground_vehicle: bool) -> None:
        self.name = autopilot
        self.ground = ground_vehicle
        self.px4 = autopilot == "px4"
        self.mav_autopilot = mavlink2.MAV_AUTOPILOT_PX4 if self.px4 else mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA
        self.mav_type = mavlink2.MAV_TYPE_GROUND_ROVER if ground_vehicle else mavlink2.MAV_TYPE_QUADROTOR
        self.home_is_item0 = not self.px4
        self.params: dict[str, float] = dict(PX4_PARAMS if self.px4 else ARDUPILOT_PARAMS)
        # flight_sw_version: major << 24 | minor << 16 | patch << 8 | FIRMWARE_VERSION_TYPE_OFFICIAL
        major, minor = (1, 14) if self.px4 else (4, 5)
        self.sw_version = major << 24 | minor << 16 | 0 << 8 | 255

    def custom_mode(self, mode: Mode) -> int:
        if self.px4:
            main, sub = _PX4_REPORT[mode]
            return main << 16 | sub << 24
        return (_ROVER_REPORT if self.ground else _COPTER_REPORT)[mode]

    def mode_from_command(self, custom: float, sub: float) -> Mode | None:
        """Mode requested by DO_SET_MODE (param2 = custom mode, param3 = custom sub mode)."""
        if self.px4:
            return _PX4_ACCEPT.get((int(custom), int(sub) if int(custom) == 4 else 0))
        return (_ROVER_ACCEPT if self.ground else _COPTER_ACCEPT).get(int(custom))

    def mode_from_set_mode(self, custom_mode: int) -> Mode | None:
        """Mode requested by the SET_MODE message (custom_mode as reported in HEARTBEAT)."""
        if self.px4:
            return self.mode_from_command((custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF)
        return self.mode_from_command(custom_mode, 0)

    # -- parameters with flavour-specific names and units ----------------------------------
    def takeoff_alt(self) -> float:
        return self.params["MIS_TAKEOFF_ALT"] if self.px4 else self.params["PILOT_TKOFF_ALT"] / 100.0

    def rtl_alt(self) -> float:
        return self.params["RTL_RETURN_ALT"] if self.px4 else self.params["RTL_ALT"] / 100.0

    def cruise_speed(self) -> float:
        if self.px4:
            return self.params["MPC_XY_CRUISE"]
        return self.params["WPNAV_SPEED"] / 100.0

    def set_cruise_param(self, speed: float) -> None:
        if self.px4:
            self.params["MPC_XY_CRUISE"] = speed
        else:
            self.params["WPNAV_SPEED"] = speed * 100.0

    def disarm_delay(self) -> float:
        return self.params["COM_DISARM_LAND"] if self.px4 else self.params["DISARM_DELAY"]
