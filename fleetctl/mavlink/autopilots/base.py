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

Field safety (docs/field-safety.md): :attr:`Autopilot.failsafe_param_names` are read to tell what
the vehicle does when the link drops (:meth:`describe_failsafe`, :meth:`failsafe_action`);
:meth:`failsafe_params` gives the values for ``links.failsafe`` and :meth:`fence_params` those that
enable an uploaded geofence with its height limit and breach action.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

from pymavlink.dialects.v20 import ardupilotmega as mavlink2


class Vehicle(Protocol):
    """What an autopilot needs of a vehicle (:class:`fleetctl.mavlink.vehicle.Vehicle` is one)."""

    name: str
    mode: str | None
    armed: bool
    mission_current: int | None
    mission_current_reports: int
    alt: float | None  # metres AMSL (GLOBAL_POSITION_INT.alt)

    @property
    def home_amsl(self) -> float | None: ...

    @property
    def on_ground(self) -> bool | None: ...

    async def command(self, command: int, params: Iterable[float] = (), *, frame: int | None = None,
                      check: bool = True, timeout: float | None = None) -> Any: ...

    async def set_mode(self, mode: str, *, settle: float = 0.0) -> None: ...

    async def set_current(self, seq: int) -> None: ...

    async def wait_until(self, predicate: Callable[[Any], bool], timeout: float, what: str = "") -> None: ...


SPEED_QUANTITIES = ("max_speed", "accel", "climb_rate", "land_speed")


@dataclass(frozen=True)
class SpeedParam:
    """A firmware parameter that decides how fast a vehicle flies or drives: ``name`` on the
    firmware, the mission ``quantity`` it corresponds to (one of :data:`SPEED_QUANTITIES`: the
    mission's ``rovers.*`` for a multicopter, ``carrier.*`` for a ground vehicle) and ``scale``,
    firmware units per SI unit (100 for cm/s)."""

    name: str
    quantity: str
    scale: float = 1.0
    lo: float | None = None  # the range the firmware flies safely, in its units (values are clamped)
    hi: float | None = None

    def value(self, si: float) -> float:
        v = si * self.scale
        if self.lo is not None:
            v = max(v, self.lo)
        if self.hi is not None:
            v = min(v, self.hi)
        return v


M = mavlink2
Params = Mapping[str, float | None]  # parameter name -> value read (None = not answered)
MODES = ("HOLD", "GUIDED", "MISSION", "TAKEOFF", "LAND", "RTL", "MANUAL")
CUSTOM = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED


class ModeError(ValueError):
    """A flight mode this autopilot does not have."""


class Autopilot:
    """Base class: firmware-independent defaults. Subclasses override the mode tables."""

    name = "generic"
    home_is_item0 = False  # True: mission item 0 is home (ArduPilot)
    # NAV_WAYPOINT param2 written into compiled missions (m), so that "reached" means at the point;
    # None = 0, the firmware's own default (PX4: NAV_ACC_RAD, 10 m on a multicopter)
    acceptance_radius: float | None = None
    param_bytewise = False  # integer parameters' bytes in PARAM_VALUE's float (PX4), else cast
    # the current mission item is set with the MISSION_SET_CURRENT message straight away (PX4 1.18
    # answers DO_SET_MISSION_CURRENT with MAV_RESULT_UNSUPPORTED: asking first costs a round trip)
    set_current_by_message = False

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

    # -- mission items ---------------------------------------------------------------------------------
    def unset_param4(self, command: int) -> float:
        """``param4`` (yaw) of a mission item that leaves the heading to the vehicle: NaN."""
        return math.nan

    @property
    def upload_hold_mode(self) -> str:
        """The mode a vehicle flying a mission is put in before its mission is replaced."""
        return "HOLD"

    @property
    def landing_ends_mission(self) -> bool:
        """A NAV_LAND inside a mission ends it: the vehicle disarms on the ground and the items
        after it never run (ArduCopter). An operation's sortie then ends at a task worked on the
        ground, and the controller times the work and starts the rest (docs/operations.md)."""
        return False

    @property
    def reposition_amsl(self) -> bool:
        """DO_REPOSITION's altitude is always taken as AMSL, whatever the COMMAND_INT frame says (PX4's
        navigator): :meth:`Vehicle.goto` sends it AMSL (``MAV_FRAME_GLOBAL_INT``)."""
        return False

    @property
    def mission_landing_settles(self) -> bool:
        """A mission's NAV_LAND made current under a hovering vehicle first flies to the item's
        location and settles there before it descends (ArduCopter: seconds). Such a vehicle
        already above its landing point is brought straight down with :meth:`Vehicle.land`
        (its landing mode) instead."""
        return False

    @property
    def land_travel(self) -> float:
        """Seconds of its horizontal velocity a multirotor sent down by :meth:`Vehicle.land` (its
        landing mode) travels on before it touches down: where it comes down is its position plus
        its velocity times this (0: where it is)."""
        return 0.0

    @property
    def stands_disarmed(self) -> bool:
        """A ground vehicle of this firmware does not stand still on its own at a mission stop: it is
        disarmed once it stands on a stop, while rovers take off from it or land on it, and armed
        again when it leaves (:meth:`fleetctl.run.carrier.CarrierControl.hold_on_stop`)."""
        return False

    @property
    def follows_braking_carrier(self) -> bool:
        """A rover near its collection stop is sent (``DO_REPOSITION``) where the carrier brakes to
        while it comes in, instead of being moved across once the carrier is parked
        (``fleetctl.run.collect.FOLLOW_STEP``): for autopilots whose repositioning was measured to
        gain by it."""
        return True

    @property
    def disarm_when_landed(self) -> bool:
        """The firmware waits seconds after its land detector before it disarms itself (PX4:
        ``COM_DISARM_LAND``, 2 s): a rover it reports landed on the deck is told to disarm at once
        (a plain disarm, which the firmware accepts only once it detected the landing)."""
        return False

    def speed_params(self) -> tuple[SpeedParam, ...]:
        """The parameters that decide this vehicle's flight times (none known here)."""
        return ()

    def speed_values(self, quantities: Mapping[str, float | None]) -> dict[str, float]:
        """Parameter values for the mission's speeds (``max_speed``, ``accel``, ``climb_rate``,
        ``land_speed`` in SI units; None = not given), clamped to the firmware's safe range."""
        return {p.name: p.value(q) for p in self.speed_params()
                if (q := quantities.get(p.quantity)) is not None}

    def planned_accel(self, speed: float, accel: float | None) -> float | None:
        """The acceleration a leg of this firmware takes in the time model (rest to rest at
        ``speed``, its parameters set to ``accel``): ``accel`` unless measured otherwise."""
        return accel

    def planned_turn_rate(self, turn_rate: float | None) -> float | None:
        """The turn rate (rad/s) a carrier of this firmware is planned with: what a radian of heading
        change between two legs costs it as it drives them; ``turn_rate`` unless measured otherwise."""
        return turn_rate

    def handling_times(self, climb_rate: float, land_speed: float, load_time: float = 0.0,
                       deck_height: float = 0.0) -> tuple[float, float] | None:
        """The time model's take-off clearance and touch-down (``rovers.takeoff_time``,
        ``rovers.land_time``, s) as this firmware flies them with these vertical speeds, the
        touch-down on a deck ``deck_height`` above the carrier's position (a descent of
        ``flight.descent(deck_height)``); None = not measured (the mission's defaults stand). The
        time model adds the carrier's ``load_time`` after the touch-down term, while the run counts
        it from the touch-down, as the autopilot disarms the rover: the touch-down term holds only
        the part of that disarm ``load_time`` does not cover."""
        return None

    # -- firmware-specific sequences ------------------------------------------------------------------
    async def arm(self, vehicle: Vehicle, force_param: float = 0.0) -> None:
        """Arm (COMPONENT_ARM_DISARM); ``force_param`` is param2 (the force magic or 0)."""
        await vehicle.command(M.MAV_CMD_COMPONENT_ARM_DISARM, (1, force_param))

    async def takeoff(self, vehicle: Vehicle, height: float) -> None:
        """Take off to ``height`` metres above home (the vehicle must be armed)."""
        await vehicle.command(M.MAV_CMD_NAV_TAKEOFF, (0, 0, 0, math.nan, 0, 0, height))

    async def start_mission(self, vehicle: Vehicle, first: int = 0) -> None:
        """Fly the uploaded mission from its current item (or ``first`` if > 0)."""
        await vehicle.command(M.MAV_CMD_MISSION_START, (first, 0))

    async def after_upload(self, vehicle: Vehicle) -> None:
        """What a new mission needs before it can be started (nothing here)."""

    # -- telemetry rates ------------------------------------------------------------------------------
    def stream_rates(self, position_hz: float, status_hz: float) -> dict[str, float]:
        """Message name -> rate (Hz) asked for at connect with SET_MESSAGE_INTERVAL, in the order
        sent; a rate < 0 turns a message off (a firmware's high-rate messages fleetctl does not
        read, which would flood a large fleet's link)."""
        return {"GLOBAL_POSITION_INT": position_hz, "BATTERY_STATUS": status_hz, "SYS_STATUS": status_hz,
                "EXTENDED_SYS_STATE": status_hz, "MISSION_CURRENT": status_hz}

    # -- link loss and geofence parameters ----------------------------------------------------------
    @property
    def failsafe_param_names(self) -> tuple[str, ...]:
        """The parameters that decide what the vehicle does when the GCS link drops."""
        return ()

    def failsafe_action(self, params: Params) -> str | None:
        """The generic link-loss action - ``none``, ``hold``, ``land``, ``rtl``, ``continue``,
        ``terminate`` (or a firmware phrase) - from :attr:`failsafe_param_names`; None = unknown."""
        return None

    def describe_failsafe(self, params: Params) -> str:
        """One line: what the vehicle does if the link drops (e.g. ``link loss: RTL after 10 s``)."""
        return "link loss: unknown (no failsafe parameters known for this autopilot)"

    def failsafe_params(self, action: str, current: Params | None = None) -> dict[str, float]:
        """Parameter values making the link-loss action ``action`` (hold | land | rtl); ``keep``
        gives none. ``current`` (the values read) keeps unrelated bits of bitmask parameters."""
        if action == "keep":
            return {}
        raise ModeError(f"{self.name} autopilot: link-loss failsafe parameters unknown; "
                        "use links.failsafe: keep")

    def fence_params(self, alt_max: float | None, action: str) -> dict[str, float]:
        """Parameter values enabling the uploaded fence with ``alt_max`` (m above home, None = no
        limit) and the breach ``action`` (report | hold | rtl | land)."""
        raise ModeError(f"{self.name} autopilot: geofence parameters unknown")


def base_mode_name(base_mode: int) -> str:
    if base_mode & M.MAV_MODE_FLAG_AUTO_ENABLED:
        return "AUTO"
    if base_mode & M.MAV_MODE_FLAG_GUIDED_ENABLED:
        return "GUIDED"
    if base_mode & M.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED:
        return "MANUAL"
    return "UNKNOWN"



def seconds(v: float | None) -> str:
    return "?" if v is None else f"{v:g} s"


def code(params: Params, name: str) -> int | None:
    v = params.get(name)
    return None if v is None else int(round(v))


__all__ = ["CUSTOM", "MODES", "SPEED_QUANTITIES", "Autopilot", "ModeError", "Params", "SpeedParam", "Vehicle",
           "base_mode_name", "code", "seconds"]
