"""ArduPilot (Copter and Rover): mode numbers, GUIDED take-off, mission item 0 = home."""

from __future__ import annotations

import math

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from fleetctl.mavlink.autopilots.base import (
    CUSTOM,
    Autopilot,
    ModeError,
    Params,
    SpeedParam,
    Vehicle,
    base_mode_name,
    code,
    seconds,
)
from fleetctl.mission.flight import TAKEOFF_HEIGHT, descent

M = mavlink2
# ArduCopter FS_GCS_ENABLE (after FS_GCS_TIMEOUT s; FS_OPTIONS bit 1 = 2: continue a mission in AUTO)
COPTER_GCS = {0: "none", 1: "rtl", 2: "continue mission in AUTO, else rtl", 3: "SmartRTL or rtl",
              4: "SmartRTL or land", 5: "land", 6: "DO_LAND_START in AUTO, else rtl",
              7: "brake (hold) or land"}
# ArduRover: FS_GCS_ENABLE 0 off, 1 on, 2 on but continue a mission in AUTO; the action is FS_ACTION
ROVER_FS_ACTION = {0: "none", 1: "rtl", 2: "hold", 3: "SmartRTL or rtl", 4: "SmartRTL or hold",
                   5: "terminate", 6: "loiter or hold"}
GCS_CONTINUE_IF_AUTO = 2  # FS_OPTIONS bit
_COPTER_SET = {"rtl": 1, "land": 5, "hold": 7}
_ROVER_SET = {"rtl": 1, "hold": 2, "land": 2}  # a ground vehicle stops
_COPTER_FENCE = {"report": 0, "rtl": 1, "land": 2, "hold": 4}  # FENCE_ACTION (4 = brake or land)
_ROVER_FENCE = {"report": 0, "rtl": 1, "hold": 2, "land": 2}
FENCE_TYPE_ALT_MAX, FENCE_TYPE_POLYGON = 1, 4
# param4 may be NaN ("keep the heading") only on these commands; any other is rejected with
# MAV_MISSION_INVALID_PARAM4 (ArduPilot's AP_Mission::mavlink_int_to_mission_cmd)
NAN_PARAM4_OK = frozenset({M.MAV_CMD_NAV_WAYPOINT, M.MAV_CMD_NAV_LAND, M.MAV_CMD_NAV_TAKEOFF,
                           M.MAV_CMD_NAV_VTOL_TAKEOFF, M.MAV_CMD_NAV_VTOL_LAND})
COPTER_SPEEDS = (SpeedParam("WPNAV_SPEED", "max_speed", 100.0, 20.0, 2000.0),
                 SpeedParam("WPNAV_ACCEL", "accel", 100.0, 50.0, 500.0),
                 SpeedParam("WPNAV_ACCEL_Z", "accel", 100.0, 50.0, 500.0),  # the time model's line is 3D
                 SpeedParam("WPNAV_SPEED_UP", "climb_rate", 100.0, 10.0, 1000.0),
                 # a leg is the time model's straight 3D line at max_speed: not slowed on the way down
                 SpeedParam("WPNAV_SPEED_DN", "max_speed", 100.0, 10.0, 500.0),
                 SpeedParam("LAND_SPEED", "land_speed", 100.0, 30.0, 200.0))
ROVER_SPEEDS = (SpeedParam("WP_SPEED", "max_speed", 1.0, 0.0, 100.0),
                SpeedParam("CRUISE_SPEED", "max_speed", 1.0, 0.0, 100.0),
                SpeedParam("WP_ACCEL", "accel", 1.0, 0.0, 10.0),
                SpeedParam("ATC_ACCEL_MAX", "accel", 1.0, 0.0, 10.0))
# ArduCopter's handling as measured on SITL (docs/autopilots.md; vehicle seconds): from MISSION_START to
# clear of the deck takes the motors' spool-up and the take-off throttle ramp (TKOFF_SLEW_TIME) on top
# of the climb (a rover armed 2 s before, as at a deployment stop; armed and started at once it lifts
# off 2 s later). A leg from rest to rest takes 3.3 - 3.6 s more than the trapezoid (the S-curve's
# jerk-limited start and its slow-down into the waypoint: 3 deployment legs and 3 collection legs on
# ArduCopter's own physics, 4 on sitl.json_physics). A rover hovering over its stop is brought down in
# LAND mode (Autopilot.mission_landing_settles: its mission's NAV_LAND first flies to the item and
# settles, up to 4 s more); from the LAND command to the rover loaded - down 3 m at LAND_SPEED 2 m/s,
# the land detector, "Disarming motors" about 1.9 s after the touch-down and its HEARTBEAT up to 0.5 s
# later - took 4.2 - 4.9 s over 12 landings (bench/firmware.py seeds 1, 2, 3, 7, own physics): 0.75 s on
# average beyond the descent and the 2.2 s disarm. An ArduRover carrier that turned sharply into a short
# leg comes to rest up to 1.3 m beside the stop (not its WP_RADIUS: the same with 0.5 m): the rovers are
# sent where it brakes to while it comes in (fleetctl.run.carrier_rest), then brought over it once it is
# parked; 1.0 s beyond the descent fits 14 collections (bench/firmware.py seeds 501 - 514: -8.8 ...
# +4.5 %; 1.5 s when a rover was moved across after the carrier parked). The carrier's load_time runs from the
# touch-down (fleetctl.run.collect), alongside the auto-disarm: the touch-down term counts only the part
# of the disarm that load_time does not cover.
COPTER_TAKEOFF_OVERHEAD = 2.6  # s
COPTER_TOUCHDOWN_OVERHEAD = 1.0  # s over its stop -> at rest on the deck beyond 3 m / LAND_SPEED
COPTER_DISARM_DELAY = 2.2  # s from the touch-down to the auto-disarm seen (its HEARTBEAT)
COPTER_LEG_OVERHEAD = 3.4  # s a waypoint leg takes beyond S/v + v/a (jerk-limited S-curve, stop at the end)
# ArduRover (own physics, WP_RADIUS 2 m, 22 legs of 3 - 30 m turning 0 - 180 deg at 2 and 3 m/s,
# from MISSION_START to at rest): a leg takes ROVER_LEG_OVERHEAD beyond the trapezoid S/v + v/a
# (2 sqrt(S/a) below v^2/a) and ROVER_TURN_COST per radian of heading change (it steers onto the new
# heading while it drives, slowing the more the sharper the turn; the time model turns it on the spot
# before the leg), least squares; 1.0 s rms, 2.3 s at worst
ROVER_LEG_OVERHEAD = 0.9  # s
ROVER_TURN_COST = 1.5  # s per rad
LAND_SPEED_RANGE = (0.3, 2.0)  # m/s: LAND_SPEED's range


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

    # -- mission items and their replacement ----------------------------------------------------------
    def unset_param4(self, command: int) -> float:
        return math.nan if command in NAN_PARAM4_OK else 0.0

    @property
    def upload_hold_mode(self) -> str:
        # Copter: GUIDED holds where it is (LOITER would follow the RC sticks); Rover: HOLD
        return "HOLD" if self.ground else "GUIDED"

    @property
    def landing_ends_mission(self) -> bool:
        # Copter 4.6: "Disarming motors" about 1 s after a mission's NAV_LAND touches down, then the
        # mission restarts at item 1 ("Mission: 1 Takeoff"); a NAV_DELAY after it never runs
        return not self.ground

    @property
    def mission_landing_settles(self) -> bool:
        # Copter 4.6 SITL: "Mission: 3 Land" on a copter hovering over the item's location, and
        # 3.5-4 s (speed-up 4) to the LANDING state: the item's FlyToLocation waits for the
        # S-curve to the (same) point to finish; LAND mode starts descending within 0.4 s
        return not self.ground

    def speed_params(self) -> tuple[SpeedParam, ...]:
        return ROVER_SPEEDS if self.ground else COPTER_SPEEDS

    def planned_accel(self, speed: float, accel: float | None) -> float | None:
        if accel is None:
            return accel
        return speed / (speed / accel + (ROVER_LEG_OVERHEAD if self.ground else COPTER_LEG_OVERHEAD))

    def planned_turn_rate(self, turn_rate: float | None) -> float | None:
        return 1.0 / ROVER_TURN_COST if self.ground else turn_rate

    def handling_times(self, climb_rate: float, land_speed: float, load_time: float = 0.0,
                       deck_height: float = 0.0) -> tuple[float, float] | None:
        if self.ground:
            return None
        land = min(max(land_speed, LAND_SPEED_RANGE[0]), LAND_SPEED_RANGE[1])
        disarm_left = max(0.0, COPTER_DISARM_DELAY - load_time)  # what load_time does not cover
        return (TAKEOFF_HEIGHT / climb_rate + COPTER_TAKEOFF_OVERHEAD,
                descent(deck_height) / land + COPTER_TOUCHDOWN_OVERHEAD + disarm_left)

    # -- arming, take-off and mission start -----------------------------------------------------------
    async def arm(self, vehicle: Vehicle, force_param: float = 0.0) -> None:
        # stock Copter (AUTO_OPTIONS 0) refuses to arm in AUTO and will not take off in AUTO after
        # arming in another mode; armed in GUIDED, MISSION_START flies the mission
        if not self.ground and not vehicle.armed and vehicle.mode != "GUIDED":
            await vehicle.set_mode("GUIDED")
        await vehicle.command(M.MAV_CMD_COMPONENT_ARM_DISARM, (1, force_param))

    async def takeoff(self, vehicle: Vehicle, height: float) -> None:
        if self.ground:
            raise ModeError(f"{vehicle.name}: a ground vehicle cannot take off")
        if vehicle.mode != "GUIDED":
            await vehicle.set_mode("GUIDED")
        await vehicle.command(M.MAV_CMD_NAV_TAKEOFF, (0, 0, 0, 0, 0, 0, height))

    async def start_mission(self, vehicle: Vehicle, first: int = 0) -> None:
        # item 0 is home; a mission replaced in flight keeps the old current index, so the first
        # item is set explicitly. MISSION_START with a first/last item is denied: it switches to
        # AUTO, which resumes at the current item.
        first = max(first, 1)
        if vehicle.mission_current != first:
            await vehicle.set_current(first)
        await vehicle.command(M.MAV_CMD_MISSION_START, (0, 0))

    # -- link loss and geofence -------------------------------------------------------------------
    @property
    def failsafe_param_names(self) -> tuple[str, ...]:
        if self.ground:
            return ("FS_GCS_ENABLE", "FS_ACTION", "FS_TIMEOUT")
        return ("FS_GCS_ENABLE", "FS_GCS_TIMEOUT", "FS_OPTIONS")

    def failsafe_action(self, params: Params) -> str | None:
        enable = code(params, "FS_GCS_ENABLE")
        if enable is None:
            return None
        if enable == 0:
            return "none"
        if self.ground:
            act = code(params, "FS_ACTION")
            what = "?" if act is None else ROVER_FS_ACTION.get(act, f"FS_ACTION {act}")
            return f"continue mission in AUTO, else {what}" if enable == 2 else what
        what = COPTER_GCS.get(enable, f"FS_GCS_ENABLE {enable}")
        opts = code(params, "FS_OPTIONS") or 0
        if opts & GCS_CONTINUE_IF_AUTO and not what.startswith("continue"):
            what = f"continue mission in AUTO, else {what}"
        return what

    def describe_failsafe(self, params: Params) -> str:
        act = self.failsafe_action(params)
        if act is None:
            return "link loss: unknown (FS_GCS_ENABLE not read)"
        if act == "none":
            return "link loss: none (FS_GCS_ENABLE 0)"
        timeout = params.get("FS_TIMEOUT" if self.ground else "FS_GCS_TIMEOUT")
        return f"link loss: {act.replace('rtl', 'RTL')} after {seconds(timeout)}"

    def failsafe_params(self, action: str, current: Params | None = None) -> dict[str, float]:
        if action == "keep":
            return {}
        if self.ground:
            return {"FS_GCS_ENABLE": 1.0, "FS_ACTION": float(_ROVER_SET[action])}
        out = {"FS_GCS_ENABLE": float(_COPTER_SET[action])}
        opts = code(current or {}, "FS_OPTIONS")
        if opts is None or opts & GCS_CONTINUE_IF_AUTO:  # the action applies in AUTO too
            out["FS_OPTIONS"] = float((opts or 0) & ~GCS_CONTINUE_IF_AUTO)
        return out

    def fence_params(self, alt_max: float | None, action: str) -> dict[str, float]:
        actions = _ROVER_FENCE if self.ground else _COPTER_FENCE
        ftype = FENCE_TYPE_POLYGON | (FENCE_TYPE_ALT_MAX if alt_max is not None and not self.ground else 0)
        out = {"FENCE_ENABLE": 1.0, "FENCE_ACTION": float(actions[action]), "FENCE_TYPE": float(ftype)}
        if alt_max is not None and not self.ground:
            out["FENCE_ALT_MAX"] = float(alt_max)
        return out
