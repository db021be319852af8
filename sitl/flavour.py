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
    # link loss (data link = GCS heartbeat) and geofence, with PX4's defaults
    "NAV_DLL_ACT": 0.0,  # 0 disabled, 1 hold, 2 return, 3 land, 5 terminate, 6 lockdown
    "COM_DL_LOSS_T": 10.0,  # s without a GCS heartbeat until the data link counts as lost
    "GF_ACTION": 1.0,  # 0 none, 1 warning, 2 hold, 3 return, 4 terminate, 5 land
    "GF_MAX_VER_DIST": 0.0,  # m above home, 0 = no altitude limit
}
ARDUPILOT_PARAMS = {
    "PILOT_TKOFF_ALT": 250.0,  # cm
    "RTL_ALT": 0.0,  # cm, 0 = the current height
    "WPNAV_SPEED": 0.0,  # cm/s, 0 = the vehicle's max speed
    "WP_RADIUS": 0.5,
    "DISARM_DELAY": 2.0,  # s after touchdown until auto-disarm
    "FENCE_ENABLE": 0.0,
    "FENCE_ACTION": 1.0,
    "FENCE_ALT_MAX": 100.0,  # m
}
# ArduCopter: FS_GCS_ENABLE 0 disabled, 1 RTL, 2 continue mission in AUTO (else RTL), 3 SmartRTL or
# RTL, 4 SmartRTL or land, 5 land, 6 auto DO_LAND_START or RTL, 7 brake or land; FS_OPTIONS bit 1
# (2) continues a mission in AUTO; FENCE_ACTION 0 report, 1 RTL or land, 2 land, 3 SmartRTL or RTL
# or land, 4 brake or land, 5 SmartRTL or land; FENCE_TYPE bit 0 max altitude, bit 2 polygon.
COPTER_SAFETY_PARAMS = {"FS_GCS_ENABLE": 0.0, "FS_GCS_TIMEOUT": 5.0, "FS_OPTIONS": 0.0, "FENCE_TYPE": 7.0}
# ArduRover: FS_GCS_ENABLE 0 disabled, 1 enabled, 2 enabled but continue a mission in AUTO; the
# action is FS_ACTION (0 nothing, 1 RTL, 2 hold, 3 SmartRTL or RTL, 4 SmartRTL or hold) after
# FS_TIMEOUT; FENCE_ACTION 0 report, 1 RTL or hold, 2 hold, 3 SmartRTL or RTL or hold, 4 SmartRTL or hold.
ROVER_SAFETY_PARAMS = {"FS_GCS_ENABLE": 0.0, "FS_ACTION": 2.0, "FS_TIMEOUT": 1.5, "FENCE_TYPE": 6.0}
FIRST_FENCE_LOAD_S = 0.45  # PX4: see Flavour.fence_load_time
_PX4_DLL = {1: "hold", 2: "rtl", 3: "land", 5: "land", 6: "land"}  # terminate/lockdown: the sim lands
_PX4_GF = {1: "report", 2: "hold", 3: "rtl", 4: "land", 5: "land"}
_COPTER_GCS = {1: "rtl", 2: "rtl", 3: "rtl", 4: "rtl", 5: "land", 6: "rtl", 7: "hold"}
_ROVER_FS = {1: "rtl", 2: "hold", 3: "rtl", 4: "rtl", 5: "hold", 6: "hold"}
_COPTER_FENCE = {0: "report", 1: "rtl", 2: "land", 3: "rtl", 4: "hold", 5: "rtl"}
_ROVER_FENCE = {0: "report", 1: "rtl", 2: "hold", 3: "rtl", 4: "rtl"}


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
        if not self.px4:
            self.params.update(ROVER_SAFETY_PARAMS if ground_vehicle else COPTER_SAFETY_PARAMS)
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

    def land_travel(self) -> float:
        """Seconds of its speed a multirotor sent into LAND mode while moving travels on before it
        stops over its landing point (PX4 1.18 SIH: 1.2 s; ArduCopter brakes at its acceleration)."""
        return 1.2 if self.px4 and not self.ground else 0.0

    def disarm_delay(self) -> float:
        return self.params["COM_DISARM_LAND"] if self.px4 else self.params["DISARM_DELAY"]

    @property
    def landing_ends_mission(self) -> bool:
        """ArduCopter: a NAV_LAND inside a mission disarms the vehicle on the ground and restarts the
        mission at its first item (measured on ArduCopter 4.6 SITL: "Disarming motors", then
        "Mission: 1 Takeoff"), so the items after it never run; PX4 stays armed and goes on."""
        return not self.px4 and not self.ground

    @property
    def fence_load_time(self) -> float:
        """Seconds after a vehicle's first geofence upload during which the mission mode is refused
        with MAV_RESULT_TEMPORARILY_REJECTED: PX4 1.18 SITL (SIH, speed factor 4) refused it 14-15
        times over 0.4 s of its time after a mission uploaded right behind its first fence, never
        after a later fence or without one; ArduPilot: never."""
        return FIRST_FENCE_LOAD_S if self.px4 else 0.0

    # -- link loss and geofence (what the firmware does, from its parameters) ---------------------
    def link_loss(self, in_mission: bool) -> tuple[str | None, float]:
        """(action, timeout s) on losing the GCS heartbeat: "hold" | "land" | "rtl", or None
        (disabled, or the firmware continues its mission)."""
        p = self.params
        if self.px4:
            return _PX4_DLL.get(int(p["NAV_DLL_ACT"])), p["COM_DL_LOSS_T"]
        enable = int(p["FS_GCS_ENABLE"])
        if self.ground:
            if enable == 0 or (enable == 2 and in_mission):
                return None, p["FS_TIMEOUT"]
            return _ROVER_FS.get(int(p["FS_ACTION"])), p["FS_TIMEOUT"]
        continue_auto = enable == 2 or int(p["FS_OPTIONS"]) & 2
        if enable == 0 or (continue_auto and in_mission):
            return None, p["FS_GCS_TIMEOUT"]
        return _COPTER_GCS.get(enable, "rtl"), p["FS_GCS_TIMEOUT"]

    def fence(self, has_polygon: bool) -> tuple[bool, str | None, float | None]:
        """(polygon enforced, breach action "report" | "hold" | "rtl" | "land" | None, max height
        above home or None)."""
        p = self.params
        if self.px4:
            alt = p["GF_MAX_VER_DIST"] if p["GF_MAX_VER_DIST"] > 0 else None
            return has_polygon, _PX4_GF.get(int(p["GF_ACTION"])), alt
        if p["FENCE_ENABLE"] < 0.5:
            return False, None, None
        ftype = int(p["FENCE_TYPE"])
        actions = _ROVER_FENCE if self.ground else _COPTER_FENCE
        alt = p["FENCE_ALT_MAX"] if ftype & 1 and not self.ground else None
        return has_polygon and bool(ftype & 4), actions.get(int(p["FENCE_ACTION"]), "rtl"), alt
