"""PX4: custom modes main << 16 | sub << 24, take-off at an AMSL altitude, mission start by mode."""

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


# NAV_DLL_ACT (data link loss, after COM_DL_LOSS_T s) and GF_ACTION (geofence breach) values
DLL_ACTIONS = {0: "none", 1: "hold", 2: "rtl", 3: "land", 5: "terminate", 6: "lockdown"}
GF_ACTIONS = {0: "none", 1: "warning", 2: "hold", 3: "rtl", 4: "terminate", 5: "land"}
_DLL_SET = {"hold": 1, "rtl": 2, "land": 3}
_GF_SET = {"report": 1, "hold": 2, "rtl": 3, "land": 5}
# streamed by PX4 on a ground-station link (mavlink mode Normal) and read by no part of fleetctl:
# turned off at connect. Measured on SITL (v1.18, SIH): ~370 messages/s per quadcopter, 6 of them at
# 50 Hz (ATTITUDE, ATTITUDE_QUATERNION, ATTITUDE_TARGET, POSITION_TARGET_LOCAL_NED,
# LOCAL_POSITION_NED, SERVO_OUTPUT_RAW), plus GLOBAL_POSITION_INT at 50 Hz
QUIET_STREAMS = ("ATTITUDE", "ATTITUDE_QUATERNION", "ATTITUDE_TARGET", "POSITION_TARGET_LOCAL_NED",
                 "POSITION_TARGET_GLOBAL_INT", "LOCAL_POSITION_NED", "SERVO_OUTPUT_RAW", "VFR_HUD",
                 "ALTITUDE", "SCALED_PRESSURE", "GNSS_INTEGRITY", "OPEN_DRONE_ID_LOCATION",
                 "OPEN_DRONE_ID_SYSTEM", "ESTIMATOR_STATUS", "DISTANCE_SENSOR", "VIBRATION", "CURRENT_MODE")
# After a vehicle's first geofence upload PX4 refuses the mission mode with
# MAV_RESULT_TEMPORARILY_REJECTED for a moment (SITL v1.18, speed factor 4: 14 - 15 refusals over 0.4 s
# of its time, the first 20 ms after the mission's ACK; none after a later fence or without one). The
# mode is asked again for this long (Vehicle.set_mode's settle)
MISSION_CHECK_S = 2.0  # mission s
# what decides a flight's time (all SI units: scale 1). A multicopter takes off at MPC_TKO_SPEED
# (after a MPC_TKO_RAMP_T velocity ramp), climbs between waypoints at MPC_Z_V_AUTO_UP, descends at
# MPC_Z_V_AUTO_DN and lands at MPC_LAND_SPEED below MPC_LAND_ALT2 (5 m); horizontally it cruises at
# MPC_XY_CRUISE with MPC_ACC_HOR (jerk MPC_JERK_AUTO). A ground rover (10045: Ackermann) drives at
# RO_SPEED_LIM with RO_ACCEL_LIM / RO_DECEL_LIM. Waypoints count as reached NAV_ACC_RAD early
# (10 m multicopter, 0.5 m rover; RA_ACC_RAD_MAX on an Ackermann rover) unless param2 is set.
# A multicopter with a distance sensor (the SIH quadcopter has one) touches down at MPC_LAND_CRWL
# (0.3 m/s) below MPC_LAND_ALT3, slower than the mission's land_speed: set to land_speed, it lands
# at the speed planned, as ArduCopter at LAND_SPEED. Its land detector's vertical-speed threshold,
# LNDMC_Z_VEL_MAX (0.25 m/s: PX4 ships it at MPC_LAND_CRWL / 1.2 and caps it there), is kept below
# the landing speed by that same margin, a bit more: SIH's estimator reads the quadcopter climbing
# at up to 0.33 m/s for 1 - 3 s after it stood still on the ground (PX4 1.18 SIH, 12 landings),
# which held "Landing detected" back 1.7 - 4.0 s after the touch-down with the stock threshold,
# 1.05 - 1.42 s at 0.5 m/s (the land detector's own LNDMC_TRIG_TIME is 1 s)
LAND_DETECT_RATIO = 0.8  # LNDMC_Z_VEL_MAX per m/s of land_speed (PX4's cap: 1 / 1.2)
LAND_DETECT_MAX = 0.6  # m/s: no looser, whatever the landing speed
MC_SPEED_PARAMS = (
    SpeedParam("MPC_XY_CRUISE", "max_speed", 1.0),
    SpeedParam("MPC_ACC_HOR", "accel", 1.0),
    SpeedParam("MPC_TKO_SPEED", "climb_rate", 1.0),
    # a leg is the time model's straight 3D line at max_speed: the mission's vertical limits must not
    # slow it (the caps first: PX4 flies the auto limits at most at MPC_Z_VEL_MAX_UP / _DN)
    SpeedParam("MPC_Z_VEL_MAX_UP", "max_speed", 1.0),
    SpeedParam("MPC_Z_V_AUTO_UP", "max_speed", 1.0),
    SpeedParam("MPC_Z_VEL_MAX_DN", "max_speed", 1.0),
    SpeedParam("MPC_Z_V_AUTO_DN", "max_speed", 1.0),
    SpeedParam("MPC_LAND_SPEED", "land_speed", 1.0),
    SpeedParam("MPC_LAND_CRWL", "land_speed", 1.0),
    # after MPC_LAND_CRWL, which caps it
    SpeedParam("LNDMC_Z_VEL_MAX", "land_speed", LAND_DETECT_RATIO, hi=LAND_DETECT_MAX),
)
ROVER_SPEED_PARAMS = (
    SpeedParam("RO_SPEED_LIM", "max_speed", 1.0),
    SpeedParam("RO_ACCEL_LIM", "accel", 1.0),
    SpeedParam("RO_DECEL_LIM", "accel", 1.0),
)
# A quadcopter's handling (10040), measured on SITL v1.18 SIH at speed factor 4 with MPC_TKO_SPEED 1.5,
# MPC_LAND_SPEED 0.7, MPC_XY_CRUISE 5, MPC_ACC_HOR 3 (tests/firmware; vehicle seconds, from the
# firmware's time_boot_ms):
# - a leg from rest (a collection rover hovering at its task, released: its start command -> its
#   approach waypoint 23 m away reached, 1 m radius): 7.3 - 9.2 s flying, mean 8.45 s, plus 0.3 - 0.5 s
#   from the command to the mission running (9 legs) - 2.5 s more than the trapezoid of v = 5, a = 3:
#   the jerk-limited start, and the slow-down into the waypoint (PX4 closes in at MPC_XY_TRAJ_P
#   0.5 m/s per metre: about 4 s from 8 m off to 1 m where the trapezoid brakes in 1.7 s);
# - a deployment's take-off and leg together (start -> task reached): 12.0 - 14.0 s; its take-off
#   clearance is that less the leg: 1 m / 1.5 m/s of climb + 2.7 s (take-off detection, the
#   MPC_TKO_RAMP_T velocity ramp, less the start of the leg the rover flies while it climbs). Fitted
#   first at 3.6 s on three fixed tasks 4 - 6 m up; with the legs' vertical limits at max_speed, 14
#   deployments on random tasks 15 - 30 m away, 3 - 10 m up (bench/firmware_px4.py --seed 201 ... 210)
#   were flown 0.0 - 1.5 s (mean 0.93 s) faster than planned with 3.6 s: 0.9 s less. Since a copter
#   takes off from the altitude it stands at (Px4.takeoff), 23 one-stop deployments were flown
#   -0.3 ... +1.7 s (mean 0.57 s) later than planned with 2.7 s - 15 on SIH (bench/firmware_px4.py
#   --seed 353 --rounds 16) and 8 on sitl.json_physics's deck (--deck --seed 373 --rounds 8), every
#   rover armed and started at once: 0.5 s more;
# - sent down from its approach waypoint 3 m above the carrier (MISSION_ITEM_REACHED) -> loaded
#   (its land detector reports it landed and fleetctl disarms it at once, Px4.disarm_when_landed;
#   MPC_LAND_CRWL and LNDMC_Z_VEL_MAX set from land_speed as above): 6.5 - 10.8 s, mean 8.0 s (24
#   landings of 8 collections, bench/firmware_px4.py, 2026-12-04): 0 - 3 s over the stop until the
#   carrier is parked (SIH's Ackermann carrier rolls on at 0.1 - 0.4 m/s after its stop) and
#   6.1 - 8.6 s from the land command to "Landing detected". A collection's makespan is its last
#   rover's: the term was the mean of each stop's last landing (three rovers a stop), 8.8 s, so
#   3 m / 0.7 m/s + 4.5 s. With the carrier disarmed on its stop as it reaches it (stands_disarmed)
#   no rover waits for it to read stopped: 8 collections on random tasks (seeds 315, 317, 319 - 324)
#   flew 0.34 s faster ... 1.07 s slower than planned with 2.9 s (mean 0.46 s slower): 3.4 s. The
#   carrier's load_time runs from the touch-down on
MC_TAKEOFF_OVERHEAD = 3.2  # s
MC_TOUCHDOWN_OVERHEAD = 3.4  # s approach waypoint -> landed and disarmed, beyond 3 m / MPC_LAND_SPEED
MC_LEG_OVERHEAD = 2.5  # s a waypoint leg from rest takes beyond S/v + v/a
# An Ackermann carrier (10045) cannot turn on the spot: it steers onto a new heading while it drives
# and slows into the turn. Its legs, planned with instantaneous turns, were flown late by about
# ROVER_TURN_COST per radian of heading change into them (least squares through the origin,
# bench/firmware_legs.py): 102 legs of 1.4 - 65 m turning 0 - 179 deg on sitl.json_physics (PX4 1.18,
# RO_SPEED_LIM 1 m/s, RO_ACCEL_LIM 1 m/s^2; the deck series of bench/firmware_px4.py --deck and
# bench/firmware_deck.py --px4): 0.78 s per rad, 0.87 s rms against 1.73 s without it, up to 5.1 s
# late after turning about. On SIH (78 collection legs of 0.6 - 8.6 m) the fit beside the length is
# 0.37 s per rad: SIH's rover drives faster than its speed limit (7.5 m straight in 6.4 s, where the
# trapezoid at 1 m/s takes 8.5 s) and arrives 1.5 s early on average either way. Legs from rest are
# otherwise the trapezoid: no overhead fits
ROVER_TURN_COST = 0.8  # s per rad
WAYPOINT_RADIUS = 1.0  # m: param2 of compiled waypoints ("reached" = at the point, not 10 m early)
_WORDS = {"none": "no action", "hold": "hold", "rtl": "RTL", "land": "land",
          "terminate": "flight termination", "lockdown": "lockdown (motors off)"}


class Px4(Autopilot):
    name = "px4"
    param_bytewise = True
    set_current_by_message = True
    acceptance_radius = WAYPOINT_RADIUS
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
        if not base_mode & CUSTOM:
            return base_mode_name(base_mode)
        main, sub = self._split(custom_mode)
        name = self._MAIN.get(main, f"MAIN{main}")
        return f"{name}.{self._AUTO.get(sub, f'SUB{sub}')}" if main == 4 else name

    def mode_name(self, base_mode: int, custom_mode: int) -> str:
        if base_mode & CUSTOM:
            generic = self._GENERIC.get(self._split(custom_mode))
            if generic is not None:
                return generic
        return self.firmware_mode(base_mode, custom_mode)

    def set_mode_params(self, mode: str) -> tuple[float, float, float]:
        key = mode.upper()
        if key not in self._SET:
            raise ModeError(f"PX4 has no mode {mode!r}; use one of {', '.join(sorted(self._SET))}")
        main, sub = self._SET[key]
        return float(CUSTOM), float(main), float(sub)

    async def arm(self, vehicle: Vehicle, force_param: float = 0.0) -> None:
        # a multicopter armed in mission mode flies its mission at once (SITL v1.18: a rover on the
        # ground armed ahead of its timed release, still in MISSION from its last flight, took off
        # 5.8 s early, and the start at its release sent it back to its first item: +10.7 %): it is
        # armed in HOLD, and its start is the switch to MISSION
        if not self.ground and not vehicle.armed and vehicle.mode == "MISSION":
            await vehicle.set_mode("HOLD")
        await super().arm(vehicle, force_param)

    async def takeoff(self, vehicle: Vehicle, height: float) -> None:
        # PX4 takes off to an AMSL altitude and moves its home to where it is armed. A vehicle on the
        # ground climbs from where it stands: its HOME_POSITION of the arming arrives about 0.5 s
        # after it, and the home reported before can be another ground's (SITL v1.18 SIH: a rover
        # landed beside the deck, its altitude 1 m above its first home, armed and sent up to that
        # home + 3 m hovered 2 m above its new home: collection incomplete)
        standing = vehicle.on_ground is True and vehicle.alt is not None
        home = vehicle.alt if standing else vehicle.home_amsl
        if home is None:
            raise RuntimeError(f"{vehicle.name}: home altitude unknown (no GLOBAL_POSITION_INT yet)")
        nan = math.nan
        await vehicle.command(M.MAV_CMD_NAV_TAKEOFF, (nan, 0, 0, nan, nan, nan, home + height))

    async def start_mission(self, vehicle: Vehicle, first: int = 0) -> None:
        # a mission uploaded to a vehicle that is not landed keeps the current index (MISSION_CURRENT
        # of the old mission, measured on SITL v1.18): a rover hovering at its task on item 2 would
        # start its way back at item 2 - the landing -, a carrier holding at a stop would start on
        # the new route's first hold, where a rover stays put. The first item is made current first.
        if vehicle.mission_current != first:
            await vehicle.set_current(first)
        await vehicle.set_mode("MISSION", settle=MISSION_CHECK_S)

    async def after_upload(self, vehicle: Vehicle) -> None:
        # the first item made current at once (see start_mission), so that the start is only the
        # mode switch: a rover released to fly back at its timed release leaves a round trip earlier.
        # PX4 ignores a MISSION_SET_CURRENT that comes right after its MISSION_ACK: the message is sent
        # again on the next MISSION_CURRENT that does not show it (Vehicle.set_current)
        if vehicle.mission_current not in (None, 0):
            await vehicle.set_current(0)

    @property
    def stands_disarmed(self) -> bool:
        # PX4 1.18 SIH's Ackermann carrier, armed on its stop's loiter, rolls on at 0.1 - 0.5 m/s for
        # seconds after it stopped, 1 - 2 m about the point (bench/firmware_px4.py --seed 303: a rover
        # came down 1.8 m off it, beside the deck, and took off to land again: collect +98 %)
        return self.ground

    @property
    def disarm_when_landed(self) -> bool:
        return True  # COM_DISARM_LAND: 2 s after "Landing detected"

    @property
    def follows_braking_carrier(self) -> bool:
        # PX4 1.18 SIH, bench/firmware_px4.py seeds 353 - 362: with the rovers sent where the Ackermann
        # carrier brakes to, collections flew -6.9 ... +58.1 % (4 of 10 beyond +10 %: the carrier
        # wobbles around its stop and each DO_REPOSITION switches the rover to HOLD); without, the
        # same seeds -5.9 ... +12.1 % (1 of 10)
        return False

    @property
    def mission_landing_settles(self) -> bool:
        # PX4 1.18 SIH: a mission's NAV_LAND flies to the item's point before it descends, and set a
        # rover hovering 1.2 m off the carrier down 1.6 m off it, beside the deck; LAND mode descends
        # where it hovers
        return not self.ground

    @property
    def land_travel(self) -> float:
        # PX4 1.18 SIH quadcopter: sent into LAND mode 1 m short of its hold at 0.2 - 1.3 m/s, it
        # touched down 0.2 - 2.0 m further on along its velocity, 1.2 s of it (median over 64
        # collection landings, bench/firmware_px4.py), and up to 1.2 m to the side
        return 0.0 if self.ground else 1.2

    @property
    def reposition_amsl(self) -> bool:
        return True  # PX4 1.18: a relative altitude of 3 m was flown as 3 m AMSL (the rover landed)

    def speed_params(self) -> tuple[SpeedParam, ...]:
        return ROVER_SPEED_PARAMS if self.ground else MC_SPEED_PARAMS

    def planned_accel(self, speed: float, accel: float | None) -> float | None:
        if self.ground or accel is None:
            return accel
        return speed / (speed / accel + MC_LEG_OVERHEAD)

    def planned_turn_rate(self, turn_rate: float | None) -> float | None:
        return 1.0 / ROVER_TURN_COST if self.ground else turn_rate

    def handling_times(self, climb_rate: float, land_speed: float, load_time: float = 0.0,
                       deck_height: float = 0.0) -> tuple[float, float] | None:
        if self.ground:
            return None
        # disarmed at once when landed (disarm_when_landed): load_time has no disarm to cover
        return (TAKEOFF_HEIGHT / climb_rate + MC_TAKEOFF_OVERHEAD,
                descent(deck_height) / land_speed + MC_TOUCHDOWN_OVERHEAD)

    # -- telemetry rates ------------------------------------------------------------------------------
    def stream_rates(self, position_hz: float, status_hz: float) -> dict[str, float]:
        """The unused high-rate streams off first, then what fleetctl reads. PX4 streams
        MISSION_CURRENT (1 Hz) and HOME_POSITION (0.5 Hz) itself and refuses an interval for
        MISSION_CURRENT; GPS_RAW_INT (5 Hz) is needed only for preflight."""
        rates: dict[str, float] = dict.fromkeys(QUIET_STREAMS, -1.0)
        rates.update(super().stream_rates(position_hz, status_hz))
        del rates["MISSION_CURRENT"]
        rates["GPS_RAW_INT"] = status_hz
        return rates

    # -- link loss and geofence -------------------------------------------------------------------
    @property
    def failsafe_param_names(self) -> tuple[str, ...]:
        return ("NAV_DLL_ACT", "COM_DL_LOSS_T")

    def failsafe_action(self, params: Params) -> str | None:
        act = code(params, "NAV_DLL_ACT")
        return None if act is None else DLL_ACTIONS.get(act, f"NAV_DLL_ACT {act}")

    def describe_failsafe(self, params: Params) -> str:
        act = self.failsafe_action(params)
        if act is None:
            return "link loss: unknown (NAV_DLL_ACT not read)"
        if act == "none":
            return "link loss: none (NAV_DLL_ACT 0)"
        return f"link loss: {_WORDS.get(act, act)} after {seconds(params.get('COM_DL_LOSS_T'))}"

    def failsafe_params(self, action: str, current: Params | None = None) -> dict[str, float]:
        if action == "keep":
            return {}
        return {"NAV_DLL_ACT": float(_DLL_SET[action])}

    def fence_params(self, alt_max: float | None, action: str) -> dict[str, float]:
        return {"GF_ACTION": float(_GF_SET[action]), "GF_MAX_VER_DIST": float(alt_max or 0.0)}
