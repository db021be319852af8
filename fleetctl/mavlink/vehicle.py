"""Vehicle proxies: one :class:`Vehicle` per system id on a :class:`fleetctl.mavlink.link.Link`
(the mission's whole :class:`~fleetctl.mavlink.fleet.Fleet` is in :mod:`fleetctl.mavlink.fleet`).

A ``Vehicle`` keeps the live state decoded from standard MAVLink telemetry (HEARTBEAT,
GLOBAL_POSITION_INT, HOME_POSITION, EXTENDED_SYS_STATE, BATTERY_STATUS/SYS_STATUS,
MISSION_CURRENT, MISSION_ITEM_REACHED, STATUSTEXT), emits :class:`VehicleEvent` s and offers async
commands that raise :class:`CommandRejected` when the autopilot refuses and
:class:`fleetctl.mavlink.link.LinkTimeout` when it does not answer. Firmware differences go through
``vehicle.autopilot`` (:mod:`fleetctl.mavlink.autopilots`), chosen from the first HEARTBEAT.

Events (``VehicleEvent.kind``): ``connected`` (first heartbeat), ``lost`` (nothing heard for
``heartbeat_timeout`` s of mission time: :mod:`fleetctl.mavlink.silence`), ``back`` (a heartbeat
after ``lost``), ``armed``, ``disarmed``, ``mode``
(data: mode, previous), ``landed_state`` (data: state), ``item_reached`` (data: seq),
``mission_current`` (data: seq), ``statustext`` (data: text, severity), ``geofence_breach``
(data: breach - FENCE_BREACH name, count; from FENCE_STATUS, or a "fence breach" STATUSTEXT of
an autopilot that sends none). Receive them with
``vehicle.add_listener(callback)`` or ``queue = vehicle.event_queue()``.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from fleetctl.geo import Origin, geodetic_to_local, local_to_geodetic
from fleetctl.mavlink.autopilots import Autopilot, autopilot_for
from fleetctl.mavlink.command_protocol import COMMAND_RETRIES, COMMAND_TIMEOUT
from fleetctl.mavlink.effects import Effect, current_taken, effect_of, heartbeat_shows, in_mode
from fleetctl.mavlink.fence import FENCE
from fleetctl.mavlink.link import (
    CommandAck,
    Link,
    LinkError,
    LinkTimeout,
    MissionItem,
    MissionRejected,
    command_name,
    enum_name,
)
from fleetctl.mavlink.silence import LATE_S, MissionClock, floor_wall, silence_left

log = logging.getLogger(__name__)

M = mavlink2
HOME_ALT_TOLERANCE = 50.0  # m: a ground vehicle's HOME_POSITION altitude this far off its own is wrong
FORCE_MAGIC = 21196.0  # MAV_CMD_COMPONENT_ARM_DISARM param2: force (ignore checks)
MISSION_STATE_COMPLETE = M.MISSION_STATE_COMPLETE  # MISSION_CURRENT.mission_state: the last item is done
DEFAULT_POSITION_HZ = 10.0
DEFAULT_BATTERY_HZ = 1.0
MAX_BATTERY_TIME = 86_400  # s: a BATTERY_STATUS.time_remaining above a day is not believed
SET_CURRENT_RESEND = 1.5  # s: MISSION_SET_CURRENT sent again when nothing says it was taken (at most:
# once the link's round trips are measured, after its retransmission timeout)
SET_CURRENT_PATIENCE = (COMMAND_RETRIES + 1) * COMMAND_TIMEOUT  # s in all: a command's patience
WATCH_EFFECT = 3600.0  # s: a command's effect is watched while its exchange runs (the exchange ends it)
_STATUS_REASON_S = 2.0  # a STATUSTEXT this recent explains a rejected command
MODE_RETRY_S = 0.1  # mission s between two DO_SET_MODE refused "for now" (set_mode's settle)
# position plausibility (field safety): a fix farther from the last applied one than
# JUMP_FACTOR x max_speed x dt + JUMP_SLACK_M is held back until CONFIRM_FIXES consecutive fixes
# spanning CONFIRM_S wall seconds agree with it (with no fix consistent with the old track between)
GENERIC_MAX_SPEED = 30.0  # m/s when the mission gives none
JUMP_FACTOR = 3.0
JUMP_SLACK_M = 3.0  # GPS noise between two fixes
CONFIRM_FIXES = 3
CONFIRM_S = 0.2
TRACK_LEN = 128  # positions kept for Vehicle.drift (over a second at the highest stream rate asked)
RATE_WINDOW_S = 1.0  # wall seconds over which the vehicle clock's rate (sim speed-up) is measured
# MISSION_ITEM_REACHED is believed only this near the item (plus its acceptance radius and the
# distance the vehicle may have moved since the last fix)
REACHED_RADIUS_M = 10.0
_POSITIONED_ITEMS = frozenset({M.MAV_CMD_NAV_WAYPOINT, M.MAV_CMD_NAV_LOITER_UNLIM, M.MAV_CMD_NAV_LOITER_TURNS,
                               M.MAV_CMD_NAV_LOITER_TIME, M.MAV_CMD_NAV_LAND, M.MAV_CMD_NAV_SPLINE_WAYPOINT})
_GLOBAL_FRAMES = frozenset({M.MAV_FRAME_GLOBAL, M.MAV_FRAME_GLOBAL_RELATIVE_ALT, M.MAV_FRAME_GLOBAL_INT,
                            M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, M.MAV_FRAME_GLOBAL_TERRAIN_ALT,
                            M.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT})

Listener = Callable[["VehicleEvent"], None]


class CommandRejected(Exception):
    """The autopilot answered a command with something other than MAV_RESULT_ACCEPTED."""

    def __init__(self, vehicle: str, ack: CommandAck, reason: str | None = None) -> None:
        self.vehicle = vehicle
        self.ack = ack
        self.reason = reason
        text = f"{vehicle}: {ack.command_name} rejected ({ack.result_name})"
        super().__init__(f"{text}: {reason}" if reason else text)


class VehicleEventKind(StrEnum):
    """Kinds of :class:`VehicleEvent`: what a vehicle's own messages told (not journal kinds; the
    run journals some of them under :class:`fleetctl.kinds.Ev` kinds, e.g. ``lost`` as ``link_lost``)."""

    CONNECTED = "connected"  # its first heartbeat
    LOST = "lost"  # no heartbeat for heartbeat_timeout
    BACK = "back"  # a heartbeat after it was lost
    ARMED = "armed"
    DISARMED = "disarmed"
    MODE = "mode"
    LANDED_STATE = "landed_state"
    GEOFENCE_BREACH = "geofence_breach"
    MISSION_CURRENT = "mission_current"
    ITEM_REACHED = "item_reached"
    STATUSTEXT = "statustext"


@dataclass(frozen=True)
class VehicleEvent:
    kind: VehicleEventKind
    vehicle: str
    sysid: int
    time: float  # time.monotonic()
    data: dict[str, Any] = field(default_factory=dict)


class Vehicle:
    """Live state and commands of one vehicle (system id ``sysid``) on ``link``.

    ``origin`` (the mission's ENU origin) enables :attr:`enu`; ``heartbeat_timeout`` is the
    silence (mission seconds on the clock given to :meth:`use_clock`, the wall clock until then)
    after which the vehicle is *lost* (:mod:`fleetctl.mavlink.silence`). Call :meth:`close` when
    done (it cancels the timer and unsubscribes from the link; the link itself is not closed).

    Plausibility (field safety): ``max_speed`` (m/s, default 30) bounds how far two position fixes
    may be apart: a GLOBAL_POSITION_INT farther than 3 x max_speed x dt + 3 m from the last applied
    fix (dt from the vehicle's ``time_boot_ms``, capped by the wall time elapsed times the
    vehicle clock's measured rate, so a simulated fleet's speed-up is taken into account and a
    forged time cannot stretch it) is *held*: not applied, counted in :attr:`positions_held`. It
    is adopted only when 3 consecutive fixes over at least 0.2 s agree with it; any fix consistent
    with the old track in between discards the held ones. A MISSION_ITEM_REACHED for an uploaded
    item with a position is ignored (counted in :attr:`item_reached_rejected`) when the vehicle's
    last position is farther from it than 10 m + the item's acceptance radius + what it may have
    flown since that fix.
    """

    def __init__(self, link: Link, sysid: int, *, name: str | None = None, origin: Origin | None = None,
                 heartbeat_timeout: float = 3.0, max_speed: float | None = None) -> None:
        self.link = link
        self.sysid = sysid
        self.name = name or f"sys{sysid}"
        self.origin = origin
        self.heartbeat_timeout = heartbeat_timeout
        self.compid = 1
        # identity / heartbeat
        self.autopilot: Autopilot | None = None
        self.mav_type: int | None = None
        self.system_status: int | None = None
        self.base_mode = 0
        self.custom_mode = 0
        self.armed = False
        self.mode: str | None = None  # generic (HOLD, MISSION, ...) where known, else the firmware's
        self.mode_firmware: str | None = None  # the firmware's own name (AUTO.LOITER, GUIDED, ...)
        self.connected = False  # a heartbeat was ever heard
        self.lost = False
        self.last_heartbeat: float | None = None  # time.monotonic()
        self.heartbeats = 0  # autopilot HEARTBEATs heard (a command's effect: fleetctl.mavlink.effects)
        self.confirmed_by_telemetry = 0  # commands ended by their effect in telemetry, their ACK lost
        self.mode_retries = 0  # mode switches refused "for now" and asked again (set_mode's settle)
        # position
        self.lat: float | None = None
        self.lon: float | None = None
        self.alt: float | None = None  # metres AMSL (GLOBAL_POSITION_INT.alt)
        self.relative_alt: float | None = None  # metres above home
        self.velocity: tuple[float, float, float] | None = None  # east, north, up (m/s)
        self.heading_deg: float | None = None  # compass degrees
        self.home: tuple[float, float, float] | None = None  # lat, lon, alt AMSL (HOME_POSITION)
        self.landed_state: int | None = None  # MAV_LANDED_STATE
        self.telemetry_at: float | None = None  # time.monotonic() of the last position or landed state
        self.battery_pct: float | None = None  # 0..100
        self.battery_time: float | None = None  # s of flight left (BATTERY_STATUS.time_remaining), if sent
        self.battery_at = 0.0  # time.monotonic() of the last BATTERY_STATUS
        # preflight (fleetctl.run.preflight): GPS_RAW_INT, SYS_STATUS sensors, FENCE_STATUS
        self.gps_fix_type: int | None = None  # GPS_FIX_TYPE (3 = 3D fix)
        self.gps_satellites: int | None = None
        self.sensors_present: int | None = None  # MAV_SYS_STATUS_SENSOR bits
        self.sensors_enabled: int | None = None
        self.sensors_health: int | None = None
        self.fence_breached = False
        self.fence_breach_count = 0
        self._breach_text_at = 0.0
        # mission
        self.mission_current: int | None = None
        self.mission_total: int | None = None
        self.mission_state: int | None = None
        self.items_reached: set[int] = set()
        self.mission_current_reports = 0  # MISSION_CURRENT messages heard
        self.mission_items: list[MissionItem] = []  # the last mission uploaded through this proxy
        # plausibility
        self.max_speed = max_speed if max_speed and max_speed > 0 else GENERIC_MAX_SPEED
        self.positions_held = 0
        self.item_reached_rejected = 0
        self._fix: tuple[float, float, float, int, float] | None = None  # lat, lon, alt, boot ms, wall
        self._held: list[tuple[Any, float]] = []  # fixes held back (msg, wall time)
        self._rate_anchor: tuple[int, float] | None = None  # (boot ms, wall) to measure the clock rate
        self._rate: float | None = None  # vehicle seconds per wall second
        self._time_followers: list[Callable[[str, int], None]] = []  # (name, time_boot_ms) of each position
        self._held_logged = -math.inf
        self.statustexts: deque[tuple[float, int, str]] = deque(maxlen=50)
        self._track: deque[tuple[int, float, float]] = deque(maxlen=TRACK_LEN)  # (boot ms, lat, lon) applied
        self._enu_key: tuple[float, float, float] | None = None
        self._enu: tuple[float, float, float] | None = None
        self._listeners: list[Listener] = []
        self._tick: asyncio.Future[None] | None = None
        self._lost_timer: asyncio.TimerHandle | None = None
        self._lost_due = 0.0  # time.monotonic() the silence check is due
        self._postponed = False  # this silence's check already ran late once (a busy event loop)
        self._clock = MissionClock()
        self._heard_mission: float | None = None  # mission time of the last message of this vehicle
        self._unsubscribe = link.subscribe(self._on_message, sysid=sysid)
        self._handlers: dict[str, Callable[[Any], None]] = {
            "HEARTBEAT": self._on_heartbeat,
            "GLOBAL_POSITION_INT": self._on_position,
            "HOME_POSITION": self._on_home,
            "EXTENDED_SYS_STATE": self._on_extended_state,
            "BATTERY_STATUS": self._on_battery,
            "SYS_STATUS": self._on_sys_status,
            "MISSION_CURRENT": self._on_mission_current,
            "MISSION_ITEM_REACHED": self._on_item_reached,
            "STATUSTEXT": self._on_statustext,
            "GPS_RAW_INT": self._on_gps_raw,
            "FENCE_STATUS": self._on_fence_status,
        }

    def __repr__(self) -> str:
        return f"<Vehicle {self.name} sysid={self.sysid} {self.link.url}>"

    def close(self) -> None:
        """Stop tracking: unsubscribe from the link, cancel the heartbeat timer, wake waiters."""
        self._unsubscribe()
        if self._lost_timer is not None:
            self._lost_timer.cancel()
            self._lost_timer = None
        self._wake()

    # -- derived state ------------------------------------------------------------------------------------
    @property
    def position(self) -> tuple[float, float, float] | None:
        """WGS84 latitude, longitude (degrees) and altitude AMSL (m), or None before telemetry."""
        if self.lat is None or self.lon is None or self.alt is None:
            return None
        return self.lat, self.lon, self.alt

    @property
    def position_age(self) -> float | None:
        """Wall seconds since the position now held arrived (None before any)."""
        return None if self._fix is None else max(time.monotonic() - self._fix[4], 0.0)

    @property
    def enu(self) -> tuple[float, float, float] | None:
        """Position in the mission frame (ENU east, north; z = altitude - origin altitude) via
        :func:`fleetctl.geo.geodetic_to_local`; None without telemetry or origin."""
        pos = self.position
        if pos is None or self.origin is None:
            return None
        if pos != self._enu_key:
            self._enu = geodetic_to_local(*pos, self.origin)
            self._enu_key = pos
        return self._enu

    @property
    def ground_vehicle(self) -> bool:
        return self.autopilot is not None and self.autopilot.ground

    @property
    def height(self) -> float | None:
        """Metres above home (GLOBAL_POSITION_INT.relative_alt); 0 for a ground vehicle: ArduRover
        may set its home from the barometer alone (altitude near 0), and then reports its AMSL
        altitude as the height above home."""
        if self.ground_vehicle and self.relative_alt is not None:
            return 0.0
        return self.relative_alt

    @property
    def home_amsl(self) -> float | None:
        """Home altitude AMSL: from HOME_POSITION, else altitude − relative altitude. A ground
        vehicle's home is where it stands when HOME_POSITION disagrees with its altitude by more
        than ``HOME_ALT_TOLERANCE`` (the ArduRover quirk above)."""
        if self.home is not None:
            off = self.alt is not None and abs(self.home[2] - self.alt) > HOME_ALT_TOLERANCE
            if self.ground_vehicle and off:
                return self.alt
            return self.home[2]
        if self.alt is not None and self.relative_alt is not None:
            return self.alt - self.relative_alt
        return None

    @property
    def ground_speed(self) -> float | None:
        return None if self.velocity is None else math.hypot(self.velocity[0], self.velocity[1])

    def drift(self, window: float) -> float | None:
        """How far (horizontally, m) the vehicle's positions of the last ``window`` seconds of its
        own clock (``time_boot_ms``) lie from its latest at most; None when the positions kept do not
        reach back that far. Unlike its velocity estimate, this shows a vehicle that stands:
        PX4 1.18 SIH's Ackermann carrier read 0.5 - 0.8 m/s for seconds while it moved 6 cm/s."""
        track = self._track
        if not track:
            return None
        boot, lat, lon = track[-1]
        since = boot - window * 1000.0
        if track[0][0] > since:
            return None
        far = 0.0
        for b, la, lo in reversed(track):
            if b < since:
                break
            far = max(far, _distance(lat, lon, 0.0, la, lo, 0.0))
        return far

    def slower_than(self, speed: float, window: float) -> bool:
        """Horizontally no faster than ``speed`` m/s by its velocity estimate (none counts as at
        rest) or by its positions over the last ``window`` s of its own clock (:meth:`drift` at most
        ``speed`` x ``window``): either shows a vehicle that stands."""
        if (self.ground_speed or 0.0) <= speed:
            return True
        drift = self.drift(window)
        return drift is not None and drift <= speed * window

    @property
    def battery_fraction(self) -> float | None:
        """Battery remaining in 0..1 (None if the vehicle does not report it)."""
        return None if self.battery_pct is None else self.battery_pct / 100.0

    @property
    def landed_state_name(self) -> str | None:
        if self.landed_state is None:
            return None
        return enum_name("MAV_LANDED_STATE", self.landed_state).removeprefix("MAV_LANDED_STATE_")

    @property
    def on_ground(self) -> bool | None:
        """True when EXTENDED_SYS_STATE says ON_GROUND (None when not reported)."""
        if self.landed_state is None or self.landed_state == M.MAV_LANDED_STATE_UNDEFINED:
            return None
        return self.landed_state == M.MAV_LANDED_STATE_ON_GROUND

    @property
    def critical(self) -> bool:
        """The autopilot's HEARTBEAT says MAV_STATE_CRITICAL or EMERGENCY (a failsafe: ArduPilot
        and PX4 report a critical battery so)."""
        return self.system_status in (M.MAV_STATE_CRITICAL, M.MAV_STATE_EMERGENCY)

    @property
    def last_heard_age(self) -> float | None:
        """Seconds since any message from this system (None if never)."""
        t = self.link.last_heard.get(self.sysid)
        return None if t is None else time.monotonic() - t

    # -- events ------------------------------------------------------------------------------------------
    def add_listener(self, listener: Listener) -> Callable[[], None]:
        """Call ``listener(event)`` for every :class:`VehicleEvent`; returns the remover."""
        self._listeners.append(listener)
        return lambda: self._listeners.remove(listener) if listener in self._listeners else None

    def event_queue(self, maxsize: int = 0) -> asyncio.Queue[VehicleEvent]:
        """A new queue receiving every event from now on (events are dropped when it is full)."""
        q: asyncio.Queue[VehicleEvent] = asyncio.Queue(maxsize)
        self.add_listener(lambda ev: put_event(q, ev))
        return q

    def _emit(self, kind: VehicleEventKind, **data: Any) -> None:
        ev = VehicleEvent(kind, self.name, self.sysid, time.monotonic(), data)
        log.debug("%s: %s %s", self.name, kind, data or "")
        for listener in list(self._listeners):
            try:
                listener(ev)
            except Exception:  # noqa: BLE001
                log.exception("%s: event listener failed", self.name)

    # -- waiting -------------------------------------------------------------------------------------------
    def _wake(self) -> None:
        tick, self._tick = self._tick, None
        if tick is not None and not tick.done():
            tick.set_result(None)

    async def wait_until(self, predicate: Callable[[Vehicle], bool], timeout: float,
                         what: str = "condition") -> None:
        """Return once ``predicate(vehicle)`` holds (checked after every message and event);
        ``TimeoutError`` naming the vehicle and ``what`` after ``timeout`` seconds."""
        try:
            async with asyncio.timeout(timeout):
                while not predicate(self):
                    if self._tick is None:
                        self._tick = asyncio.get_running_loop().create_future()
                    await asyncio.shield(self._tick)
        except TimeoutError:
            raise TimeoutError(f"{self.name} (sysid {self.sysid}): {what} not reached within "
                               f"{timeout:g} s") from None

    async def wait_heartbeat(self, timeout: float) -> None:
        await self.wait_until(lambda v: v.connected and not v.lost, timeout, "heartbeat")

    async def wait_item_reached(self, seq: int, timeout: float) -> None:
        """Wait until mission item ``seq`` was reached (MISSION_ITEM_REACHED, or MISSION_CURRENT
        moved past it - the reached message may be lost)."""
        await self.wait_until(
            lambda v: seq in v.items_reached or (v.mission_current is not None and v.mission_current > seq),
            timeout, f"mission item {seq}")

    # -- receive -----------------------------------------------------------------------------------------
    def _on_message(self, msg: Any) -> None:
        self._heard_mission = self._clock.now()
        self._postponed = False
        handler = self._handlers.get(msg.get_type())
        if handler is not None:
            handler(msg)
        self._wake()

    def _on_heartbeat(self, msg: Any) -> None:
        if msg.autopilot == M.MAV_AUTOPILOT_INVALID or msg.type == M.MAV_TYPE_GCS:
            return  # another component (camera, gimbal) or a ground station with this sysid
        now = time.monotonic()
        first = not self.connected
        if first or self.autopilot is None or msg.type != self.mav_type:
            self.autopilot = autopilot_for(msg)
            self.mav_type = msg.type
            self.compid = msg.get_srcComponent()
        self.connected = True
        self.last_heartbeat = now
        self.heartbeats += 1
        self.system_status = msg.system_status
        self._arm_lost_timer()
        if first:
            self._emit(VehicleEventKind.CONNECTED, autopilot=self.autopilot.name)
        elif self.lost:
            self.lost = False
            self._emit(VehicleEventKind.BACK)
        self.base_mode, self.custom_mode = msg.base_mode, msg.custom_mode
        armed = bool(msg.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)
        if armed != self.armed:
            self.armed = armed
            if not first:
                self._emit(VehicleEventKind.ARMED if armed else VehicleEventKind.DISARMED)
        mode = self.autopilot.mode_name(msg.base_mode, msg.custom_mode)
        self.mode_firmware = self.autopilot.firmware_mode(msg.base_mode, msg.custom_mode)
        if mode != self.mode:
            previous, self.mode = self.mode, mode
            self._emit(VehicleEventKind.MODE, mode=mode, previous=previous)

    def use_clock(self, now: Callable[[], float], rate: float) -> None:
        """Measure silences on the mission clock ``now`` (``rate`` mission seconds per wall second):
        ``heartbeat_timeout`` is then in mission seconds (:mod:`fleetctl.mavlink.silence`)."""
        heard = self.link.last_heard.get(self.sysid)
        if heard is not None:  # the last message's mission time, on the new clock
            self._heard_mission = now() - (time.monotonic() - heard) * rate
        self._clock = MissionClock(now, rate)
        if self._lost_timer is not None:
            self._arm_lost_timer()

    def follow_time(self, observe: Callable[[str, int], None]) -> None:
        """Tell ``observe(name, time_boot_ms)`` the vehicle's own clock with each of its positions
        (a mission clock on the vehicles' time: :mod:`fleetctl.mavlink.vehicle_clock`)."""
        if observe not in self._time_followers:
            self._time_followers.append(observe)

    def unfollow_time(self, observe: Callable[[str, int], None]) -> None:
        if observe in self._time_followers:
            self._time_followers.remove(observe)

    def _silence_left(self) -> float:
        """Wall seconds until this vehicle's silence makes it lost (zero or less: lost now)."""
        heard = self.link.last_heard.get(self.sysid)
        if heard is None:
            return 0.0
        wall = time.monotonic() - heard
        clock = self._clock
        mission = clock.now() - self._heard_mission if self._heard_mission is not None else wall * clock.rate
        return silence_left(self.heartbeat_timeout, wall, mission, clock.rate)

    def _arm_lost_timer(self, wait: float | None = None) -> None:
        if self._lost_timer is not None:
            self._lost_timer.cancel()
        wait = max(self._silence_left() if wait is None else wait, 0.001)
        self._lost_due = time.monotonic() + wait
        self._lost_timer = asyncio.get_running_loop().call_later(wait, self._on_silence)

    def _on_silence(self) -> None:
        """The silence check: lost after ``heartbeat_timeout`` of mission time without a heartbeat or
        any other of its messages (a lossy link drops heartbeats too; any message of the vehicle
        shows the link works), and at least the wall-clock floor; looked at again when a message
        came since, or once when this check ran late on a busy event loop."""
        self._lost_timer = None
        left = self._silence_left()
        late = time.monotonic() - self._lost_due > LATE_S
        if late and not self._postponed and not self.lost:
            self._postponed = True  # its messages may be waiting to be read: the floor once more
            self._arm_lost_timer(max(left, floor_wall(self.heartbeat_timeout)))
            return
        if left > 0:
            self._arm_lost_timer(left)
            return
        if not self.lost:
            self.lost = True
            log.warning("%s (sysid %d): nothing heard for %.1f s of mission time", self.name, self.sysid,
                        self.heartbeat_timeout)
            self._emit(VehicleEventKind.LOST, timeout=self.heartbeat_timeout)
            self._wake()

    def _on_position(self, msg: Any) -> None:
        now = time.monotonic()
        for observe in self._time_followers:
            observe(self.name, int(msg.time_boot_ms))
        fix = self._fix
        if fix is not None and not self._plausible(fix, msg, now):
            held = self._held
            if held and self._plausible(self._as_fix(held[-1][0], held[-1][1]), msg, now):
                held.append((msg, now))
            else:
                held[:] = [(msg, now)]
            if len(held) < CONFIRM_FIXES or now - held[0][1] < CONFIRM_S:
                self.positions_held += 1
                if now - self._held_logged > 10.0:
                    self._held_logged = now
                    log.warning("%s (sysid %d): position %.7f, %.7f is implausibly far from the track "
                                "(%.0f m); held back until confirmed", self.name, self.sysid, msg.lat / 1e7,
                                msg.lon / 1e7, _distance(fix[0], fix[1], fix[2], msg.lat / 1e7,
                                                         msg.lon / 1e7, msg.alt / 1000.0))
                return
            log.warning("%s (sysid %d): position jump confirmed by %d consecutive fixes", self.name,
                        self.sysid, len(held))
            self._rate_anchor = None
        self._held.clear()
        self._apply_position(msg, now)

    @staticmethod
    def _as_fix(msg: Any, wall: float) -> tuple[float, float, float, int, float]:
        return msg.lat / 1e7, msg.lon / 1e7, msg.alt / 1000.0, int(msg.time_boot_ms), wall

    def _plausible(self, fix: tuple[float, float, float, int, float], msg: Any, now: float) -> bool:
        lat, lon, alt, boot, wall = fix
        rate = self._rate
        cap = 30.0 if rate is None else max(now - wall, 0.1) * rate * 2.0 + 0.1
        dt = (int(msg.time_boot_ms) - boot) / 1000.0
        if not 0.0 < dt <= cap:
            dt = cap  # the vehicle clock went back (reboot) or too far forward (forged)
        dist = _distance(lat, lon, alt, msg.lat / 1e7, msg.lon / 1e7, msg.alt / 1000.0)
        return dist <= JUMP_FACTOR * self.max_speed * dt + JUMP_SLACK_M

    def _apply_position(self, msg: Any, now: float) -> None:
        boot = int(msg.time_boot_ms)
        anchor = self._rate_anchor
        if anchor is None or boot < anchor[0]:
            self._rate_anchor = (boot, now)
        elif now - anchor[1] >= RATE_WINDOW_S:
            self._rate = max((boot - anchor[0]) / 1000.0 / (now - anchor[1]), 1e-3)
            self._rate_anchor = (boot, now)
        self._fix = self._as_fix(msg, now)
        self.lat, self.lon = msg.lat / 1e7, msg.lon / 1e7
        if self._track and boot < self._track[-1][0]:
            self._track.clear()  # its clock went back: a reboot
        self._track.append((boot, self.lat, self.lon))
        self.alt = msg.alt / 1000.0
        self.relative_alt = msg.relative_alt / 1000.0
        self.velocity = (msg.vy / 100.0, msg.vx / 100.0, -msg.vz / 100.0)
        self.heading_deg = None if msg.hdg == 0xFFFF else msg.hdg / 100.0
        self.telemetry_at = now

    def _on_home(self, msg: Any) -> None:
        self.home = (msg.latitude / 1e7, msg.longitude / 1e7, msg.altitude / 1000.0)

    def _on_extended_state(self, msg: Any) -> None:
        self.telemetry_at = time.monotonic()
        if msg.landed_state != self.landed_state:
            self.landed_state = msg.landed_state
            self._emit(VehicleEventKind.LANDED_STATE, state=self.landed_state_name)

    def _on_battery(self, msg: Any) -> None:
        if msg.battery_remaining >= 0:
            self.battery_pct = float(msg.battery_remaining)
            self.battery_at = time.monotonic()
        left = getattr(msg, "time_remaining", 0)  # MAVLink 2 extension: s of flight left, 0 = none
        self.battery_time = float(left) if isinstance(left, int) and 0 < left < MAX_BATTERY_TIME else None

    def _on_sys_status(self, msg: Any) -> None:
        if msg.battery_remaining >= 0 and self.battery_pct is None:
            self.battery_pct = float(msg.battery_remaining)
        self.sensors_present = msg.onboard_control_sensors_present
        self.sensors_enabled = msg.onboard_control_sensors_enabled
        self.sensors_health = msg.onboard_control_sensors_health

    def _on_gps_raw(self, msg: Any) -> None:
        self.gps_fix_type = msg.fix_type
        self.gps_satellites = None if msg.satellites_visible == 255 else msg.satellites_visible

    def _on_fence_status(self, msg: Any) -> None:
        breached = bool(msg.breach_status)
        new = breached and (not self.fence_breached or msg.breach_count > self.fence_breach_count)
        self.fence_breached, self.fence_breach_count = breached, msg.breach_count
        if new and time.monotonic() - self._breach_text_at > 5.0:  # not told by a STATUSTEXT just now
            self._emit(VehicleEventKind.GEOFENCE_BREACH, breach=enum_name("FENCE_BREACH", msg.breach_type),
                       count=msg.breach_count)

    def _on_mission_current(self, msg: Any) -> None:
        self.mission_total = getattr(msg, "total", None)
        self.mission_current_reports += 1
        self.mission_state = getattr(msg, "mission_state", None)
        if msg.seq != self.mission_current:
            self.mission_current = msg.seq
            self._emit(VehicleEventKind.MISSION_CURRENT, seq=msg.seq)

    def _on_item_reached(self, msg: Any) -> None:
        far = self._far_from_item(msg.seq)
        if far is not None:
            self.item_reached_rejected += 1
            log.warning("%s (sysid %d): MISSION_ITEM_REACHED %d ignored: the vehicle is %.0f m from that "
                        "item", self.name, self.sysid, msg.seq, far)
            return
        if msg.seq not in self.items_reached:
            self.items_reached.add(msg.seq)
            self._emit(VehicleEventKind.ITEM_REACHED, seq=msg.seq)

    def _far_from_item(self, seq: int) -> float | None:
        """The distance to item ``seq`` when the last fix contradicts reaching it, else None."""
        items = self.mission_items
        fix = self._fix
        if fix is None or not 0 <= seq < len(items):
            return None
        it = items[seq]
        if it.command not in _POSITIONED_ITEMS or it.frame not in _GLOBAL_FRAMES or (it.x == 0 and it.y == 0):
            return None
        d = _distance(fix[0], fix[1], 0.0, it.lat, it.lon, 0.0)
        accept = it.param2 if it.command == M.MAV_CMD_NAV_WAYPOINT and math.isfinite(it.param2) else 0.0
        speed = self.ground_speed or 0.0
        stale = max(time.monotonic() - fix[4], 0.1) * (self._rate or 1.0)
        return d if d > REACHED_RADIUS_M + max(accept, 0.0) + speed * max(stale, 1.0) else None

    def _on_statustext(self, msg: Any) -> None:
        text = msg.text if isinstance(msg.text, str) else msg.text.decode("utf-8", "replace")
        text = text.split("\x00", 1)[0]
        self.statustexts.append((time.monotonic(), msg.severity, text))
        self._emit(VehicleEventKind.STATUSTEXT, text=text, severity=msg.severity)
        low = text.lower()
        if "fence" in low and "breach" in low and not self.fence_breached:  # no FENCE_STATUS (yet)
            now = time.monotonic()
            if now - self._breach_text_at > 5.0:
                self._breach_text_at = now
                self._emit(VehicleEventKind.GEOFENCE_BREACH, breach="STATUSTEXT", text=text)

    # -- commands --------------------------------------------------------------------------------------------
    def _require_autopilot(self) -> Autopilot:
        if self.autopilot is None:
            raise LinkError(f"{self.name} (sysid {self.sysid}): no heartbeat heard yet on {self.link.url}")
        return self.autopilot

    async def refresh_battery(self, timeout: float = 2.0) -> float | None:
        """Ask for a BATTERY_STATUS now (REQUEST_MESSAGE) and wait for it: streamed battery
        messages come at ~1 Hz, too stale to plan a collection from (and a simulated fleet running
        faster than real time drains more between two). The reading is the request's effect: a
        request whose ACK or whose BATTERY_STATUS is lost is sent again after the link's
        retransmission timeout until a reading heard after the first request comes (any
        BATTERY_STATUS: the streamed one too). Returns the battery %, the last known one when none
        comes within ``timeout`` s (the whole budget, retries included) or the vehicle refuses."""
        asked = time.monotonic()
        with contextlib.suppress(LinkError, CommandRejected, TimeoutError):
            async with asyncio.timeout(timeout):
                await self.request_until(mavlink2.MAVLINK_MSG_ID_BATTERY_STATUS,
                                         lambda v: v.battery_at > asked, timeout / 4)
        return self.battery_pct

    async def request_until(self, msgid: int, fresh: Effect, timeout: float) -> None:
        """REQUEST_MESSAGE ``msgid`` until ``fresh(vehicle)`` holds (the message arrived), asking
        again after each ACK that is not followed by it within the link's retransmission timeout
        (at most ``timeout``). Bound it with ``asyncio.timeout``: it asks for as long as it runs.
        :class:`CommandRejected` when the vehicle refuses to send it."""
        while not fresh(self):
            await self.command(M.MAV_CMD_REQUEST_MESSAGE, [float(msgid)], timeout=timeout, effect=fresh)
            with contextlib.suppress(TimeoutError):
                await self.wait_until(fresh, self.link.rtt.timeout(timeout), "the message asked for")

    async def command(self, command: int, params: Iterable[float] = (), *, frame: int | None = None,
                      check: bool = True, timeout: float | None = None,
                      effect: Effect | None = None) -> CommandAck:
        """Send a command (COMMAND_LONG, or COMMAND_INT when ``frame`` is given; see
        :meth:`Link.command`) with retries. ``check``: raise :class:`CommandRejected` unless accepted.

        A command whose effect shows in telemetry (``effect``, default
        :func:`fleetctl.mavlink.effects.effect_of`: arming, the mission start, the current item)
        is done, accepted, as soon as a report shows it, even when every ACK is lost: attempts go
        on at the link's retransmission timeout until the ACK or the effect comes (counted in
        :attr:`confirmed_by_telemetry` when the effect came first)."""
        p = list(params)
        kw: dict[str, Any] = {} if timeout is None else {"timeout": timeout}
        shown = effect if effect is not None else effect_of(self, command, p)
        sent = time.monotonic()
        send = self.link.command(self.sysid, command, p, compid=self.compid, frame=frame, **kw)
        ack = await send if shown is None else await self._ack_or_effect(command, send, shown)
        if check and not ack.accepted:
            reason = next((t for ts, _sev, t in reversed(self.statustexts)
                           if ts >= sent - _STATUS_REASON_S), None)
            raise CommandRejected(self.name, ack, reason)
        log.debug("%s: %s -> %s", self.name, command_name(command), ack.result_name)
        return ack

    async def _ack_or_effect(self, command: int, send: Any, shown: Effect) -> CommandAck:
        """The ACK of ``send`` (the command's exchange, not started), or an accepted one as soon as
        ``shown`` holds on a report of this vehicle (the exchange is then cancelled)."""
        exchange = asyncio.ensure_future(send)
        seen = asyncio.ensure_future(self.wait_until(shown, WATCH_EFFECT, f"{command_name(command)} done"))
        try:
            await asyncio.wait({exchange, seen}, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for t in (exchange, seen):
                t.cancel()
            await asyncio.gather(exchange, seen, return_exceptions=True)
        if exchange.done() and not exchange.cancelled() and exchange.exception() is None:
            return exchange.result()  # the ACK (it may have come with the effect: the ACK wins)
        if not shown(self):
            exc = None if exchange.cancelled() else exchange.exception()
            raise exc if exc is not None else LinkTimeout(f"{self.name}: {command_name(command)} unanswered")
        self.confirmed_by_telemetry += 1
        log.debug("%s: %s seen done in telemetry (ACK lost)", self.name, command_name(command))
        return CommandAck(self.sysid, command, M.MAV_RESULT_ACCEPTED, 0, by_effect=True)

    async def arm(self, force: bool = False) -> None:
        """Arm, in the mode the firmware takes off from (ArduCopter: GUIDED)."""
        await self._require_autopilot().arm(self, FORCE_MAGIC if force else 0.0)

    async def disarm(self, force: bool = False) -> None:
        await self.command(M.MAV_CMD_COMPONENT_ARM_DISARM, (0, FORCE_MAGIC if force else 0))

    async def hold_and_disarm(self, timeout: float = 5.0) -> None:
        """Stop where it is and disarm: the hold mode (generic ``HOLD``) unless it is in it, then
        COMPONENT_ARM_DISARM 0, confirmed by a HEARTBEAT without the armed flag within ``timeout``
        (wall s). A disarmed vehicle is left as it is."""
        if not self.armed:
            return
        if self.mode != "HOLD":
            await self.set_mode("HOLD")
        await self.disarm()
        await self.wait_until(lambda v: not v.armed, timeout, "disarmed")

    async def set_mode(self, mode: str, *, settle: float = 0.0) -> None:
        """Switch to a generic mode (HOLD, GUIDED, MISSION, TAKEOFF, LAND, RTL, MANUAL) or a
        firmware mode name, with DO_SET_MODE; done when the ACK or a HEARTBEAT showing the mode comes.

        ``settle``: for this many mission seconds a MAV_RESULT_TEMPORARILY_REJECTED answer ("valid,
        but not now: retry later", MAVLink's command protocol) is retried every
        :data:`MODE_RETRY_S`; any other refusal, or one after that, raises :class:`CommandRejected`."""
        params = self._require_autopilot().set_mode_params(mode)
        rate = max(self._clock.rate, 1e-9)
        give_up = time.monotonic() + settle / rate
        while True:
            try:
                await self.command(M.MAV_CMD_DO_SET_MODE, params, effect=heartbeat_shows(self, in_mode(mode)))
                return
            except CommandRejected as exc:
                if exc.ack.result != M.MAV_RESULT_TEMPORARILY_REJECTED or time.monotonic() >= give_up:
                    raise
                self.mode_retries += 1
                log.debug("%s: %s refused for now (%s), asked again", self.name, mode, exc.reason)
            await asyncio.sleep(MODE_RETRY_S / rate)

    async def takeoff(self, height: float) -> None:
        """Take off to ``height`` metres above home (arm first)."""
        await self._require_autopilot().takeoff(self, height)

    async def land(self, lat: float | None = None, lon: float | None = None) -> None:
        """Land here, or at ``lat``/``lon`` (degrees) when given (NAV_LAND)."""
        nan = math.nan
        if lat is None or lon is None:
            await self.command(M.MAV_CMD_NAV_LAND, (0, 0, 0, nan, nan, nan, 0))
        else:
            await self.command(M.MAV_CMD_NAV_LAND, (0, 0, 0, nan, lat, lon, 0),
                               frame=M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)

    async def goto(self, lat: float, lon: float, alt: float, speed: float | None = None) -> None:
        """Fly to ``lat``/``lon`` (degrees) at ``alt`` metres above home (DO_REPOSITION as
        COMMAND_INT, switching to the guided/hold mode that flies it). An autopilot that takes the
        altitude as AMSL whatever the frame (:attr:`Autopilot.reposition_amsl`) is sent it AMSL
        (``MAV_FRAME_GLOBAL_INT``, from :attr:`home_amsl`; unknown: NaN, its altitude kept)."""
        frame = M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        if self.autopilot is not None and self.autopilot.reposition_amsl:
            home = self.home_amsl
            frame, alt = M.MAV_FRAME_GLOBAL_INT, (math.nan if home is None else home + alt)
        await self.command(M.MAV_CMD_DO_REPOSITION,
                           (speed if speed else -1, M.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE, 0, math.nan,
                            lat, lon, alt), frame=frame)

    async def goto_enu(self, x: float, y: float, z: float, speed: float | None = None) -> None:
        """:meth:`goto` a point of the mission frame (``z`` = height above the origin altitude,
        taken as height above home)."""
        if self.origin is None:
            raise ValueError(f"{self.name}: goto_enu needs the mission origin")
        lat, lon, _alt = local_to_geodetic(x, y, z, self.origin)
        await self.goto(lat, lon, z, speed)

    async def upload_mission(self, items: list[MissionItem]) -> None:
        """Upload ``items`` as given (on ArduPilot item 0 must be home: see :mod:`fleetctl.mavlink.compile`).
        Raises :class:`fleetctl.mavlink.link.MissionRejected` with the autopilot's MAV_MISSION_RESULT (and its
        ``reason``: a STATUSTEXT the vehicle sent while refusing, if any).

        A vehicle flying a mission is first put in its hold mode (ArduCopter GUIDED, else HOLD):
        ArduPilot keeps the current index of a mission replaced in AUTO and starts whatever the new
        mission has there at once. :meth:`start_mission` then sets the first item explicitly (PX4,
        which keeps the index too, right after the upload: :meth:`Autopilot.after_upload`)."""
        if self.armed and self.mode == "MISSION" and self.autopilot is not None:
            await self.set_mode(self.autopilot.upload_hold_mode)
        sent = time.monotonic()
        try:
            await self.link.upload_mission(self.sysid, items, compid=self.compid)
        except MissionRejected as exc:
            exc.reason = next((t for ts, _sev, t in reversed(self.statustexts)
                               if ts >= sent - _STATUS_REASON_S), None)
            raise
        self.items_reached.clear()
        self.mission_items = list(items)
        if self.autopilot is not None:
            await self.autopilot.after_upload(self)

    async def upload_fence(self, items: list[MissionItem]) -> None:
        """Upload a FENCE mission (:func:`fleetctl.mavlink.fence.fence_items`)."""
        await self.link.upload_mission(self.sysid, items, compid=self.compid, mission_type=FENCE)

    async def download_fence(self) -> list[MissionItem]:
        return await self.link.download_mission(self.sysid, compid=self.compid, mission_type=FENCE)

    async def request_message(self, msgid: int, timeout: float | None = None) -> CommandAck:
        """Ask for one message now (MAV_CMD_REQUEST_MESSAGE); the ACK, accepted or not."""
        return await self.command(M.MAV_CMD_REQUEST_MESSAGE, [float(msgid)], check=False, timeout=timeout)

    async def download_mission(self) -> list[MissionItem]:
        return await self.link.download_mission(self.sysid, compid=self.compid)

    async def clear_mission(self) -> None:
        await self.link.clear_mission(self.sysid, compid=self.compid)
        self.items_reached.clear()
        self.mission_items = []

    async def start_mission(self, first: int = 0) -> None:
        """Fly the uploaded mission (from item ``first`` when > 0). Arm first.

        The current item known before the start is forgotten: it may be the index of the mission
        flown before (a stock ArduPilot carrier reports its old index until it takes the new
        mission), which would make a later item look passed at once; the next MISSION_CURRENT
        sets it again."""
        await self._require_autopilot().start_mission(self, first)
        self.mission_current = None

    async def set_current(self, seq: int) -> None:
        """Make mission item ``seq`` current (MAV_CMD_DO_SET_MISSION_CURRENT; falls back to the
        MISSION_SET_CURRENT message when the command is unsupported, as on PX4 1.18, whose
        autopilot class sends the message straight away: :attr:`Autopilot.set_current_by_message`).

        The message is confirmed by MISSION_CURRENT showing ``seq``, or - when the vehicle already
        stands within the item's acceptance radius (a carrier's next stop at or next to the one it
        holds at) and goes straight on to the next item, so that ``seq`` is never reported current -
        by MISSION_ITEM_REACHED for ``seq`` or MISSION_CURRENT past it (from an item before it)."""
        if self.autopilot is not None and self.autopilot.set_current_by_message:
            await self._set_current_message(seq)
            return
        ack = await self.command(M.MAV_CMD_DO_SET_MISSION_CURRENT, (seq, 0), check=False)
        if ack.result == M.MAV_RESULT_UNSUPPORTED:
            await self._set_current_message(seq)
            return
        if not ack.accepted:
            raise CommandRejected(self.name, ack)

    async def _set_current_message(self, seq: int) -> None:
        """MISSION_SET_CURRENT ``seq`` (no ACK: confirmed from the telemetry, see :meth:`set_current`)."""
        taken = current_taken(self, seq)

        # sent again after each MISSION_CURRENT that does not show it (PX4 ignores the message a few
        # milliseconds after the MISSION_ACK of an upload, before its navigator took the new mission:
        # SITL v1.18), or after the link's retransmission timeout (SET_CURRENT_RESEND until a round
        # trip is known) without an answer, within SET_CURRENT_PATIENCE in all
        deadline = time.monotonic() + SET_CURRENT_PATIENCE

        def answered(heard: int) -> Callable[[Vehicle], bool]:
            return lambda v: taken(v) or v.mission_current_reports > heard

        while (left := deadline - time.monotonic()) > 0:
            heard = self.mission_current_reports
            msg = self.link.mav.mission_set_current_encode(self.sysid, self.compid, seq)
            self.link.send(msg, self.sysid)
            wait = min(self.link.rtt.timeout(SET_CURRENT_RESEND), left)
            with contextlib.suppress(TimeoutError):
                await self.wait_until(answered(heard), wait, f"current item {seq}")
            if taken(self):
                return
        raise TimeoutError(f"{self.name}: MISSION_SET_CURRENT {seq} not confirmed")

    async def swap_battery(self, percent: float = 100.0) -> None:
        """Tell a rover on the deck that its battery was swapped (or charged) to ``percent``
        (MAV_CMD_BATTERY_RESET, every battery of the mask): on the simulated fleet this fills it;
        on real vehicles the swap is the operator's or a station's and this resets the autopilot's
        battery estimate. The vehicle must be disarmed on the deck."""
        await self.command(M.MAV_CMD_BATTERY_RESET, (255, percent))

    async def pause(self) -> None:
        """Hold position in the middle of a mission (DO_PAUSE_CONTINUE 0)."""
        await self.command(M.MAV_CMD_DO_PAUSE_CONTINUE, (0,))

    async def resume(self) -> None:
        """Continue a paused mission (DO_PAUSE_CONTINUE 1)."""
        await self.command(M.MAV_CMD_DO_PAUSE_CONTINUE, (1,))

    async def configure_streams(self, position_hz: float = DEFAULT_POSITION_HZ,
                                battery_hz: float = DEFAULT_BATTERY_HZ) -> dict[str, str]:
        """Ask for GLOBAL_POSITION_INT at ``position_hz`` and battery/state messages at
        ``battery_hz`` (SET_MESSAGE_INTERVAL), and turn off the firmware's high-rate messages
        fleetctl does not read (:meth:`Autopilot.stream_rates`: PX4 streams ~370 messages/s).
        Returns message name -> MAV_RESULT name (or the error); a vehicle that refuses keeps its
        default streams."""
        ap = self.autopilot or Autopilot()
        rates = ap.stream_rates(position_hz, battery_hz)

        async def one(name: str, hz: float) -> str:
            msgid = _msgid(name)
            if msgid is None:
                return "not in the MAVLink dialects"
            try:
                # turning a stream off is a saving, not a need: one resend at most
                kw = {"retries": 1} if hz < 0 else {}
                ack = await self.link.set_message_interval(self.sysid, msgid, hz, compid=self.compid, **kw)
                return ack.result_name
            except LinkError as exc:
                return str(exc)

        results = await asyncio.gather(*(one(n, hz) for n, hz in rates.items()))
        out = dict(zip(rates, results, strict=True))
        bad = {k: v for k, v in out.items() if v != "MAV_RESULT_ACCEPTED" and rates[k] >= 0}
        if bad:
            log.warning("%s: message intervals not set: %s", self.name, bad)
        still = [k for k, v in out.items() if v != "MAV_RESULT_ACCEPTED" and rates[k] < 0]
        if still:
            log.debug("%s: messages not turned off: %s", self.name, still)
        return out


def _msgid(name: str) -> int | None:
    """A message's id by name: this dialect's, else pymavlink's union of every dialect (e.g.
    GNSS_INTEGRITY, which PX4 streams)."""
    msgid = getattr(M, f"MAVLINK_MSG_ID_{name}", None)
    if msgid is None:
        from pymavlink.dialects.v20 import all as every

        msgid = getattr(every, f"MAVLINK_MSG_ID_{name}", None)
    return None if msgid is None else int(msgid)


def _distance(lat1: float, lon1: float, alt1: float, lat2: float, lon2: float, alt2: float) -> float:
    """Metres between two nearby geodetic points (equirectangular; plenty for plausibility)."""
    k = 111_319.49
    dn = (lat2 - lat1) * k
    de = (lon2 - lon1) * k * math.cos(math.radians((lat1 + lat2) / 2))
    return math.sqrt(dn * dn + de * de + (alt2 - alt1) ** 2)


def put_event(q: asyncio.Queue[VehicleEvent], ev: VehicleEvent) -> None:
    with contextlib.suppress(asyncio.QueueFull):
        q.put_nowait(ev)


__all__ = ["CommandRejected", "Listener", "Vehicle", "VehicleEvent", "VehicleEventKind"]
