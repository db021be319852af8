"""The simulated autopilot of one vehicle: MAVLink message handling, commands, the mission
protocol, the mission executor and telemetry streams.

Timing: physics, mission hold times and auto-disarm run on simulated time (``clock.sim_time``);
telemetry streams run at their rates per simulated second, as a firmware in software-in-the-loop
sends them at a speed-up, and never slower than per wall second (``clock.stream_time``); protocol
timeouts run on wall time (``clock.wall()``), like the ground station's own timeouts.
"""

from __future__ import annotations

import logging
import math
import time
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from . import mission as ms
from .config import VehicleSpec
from .faults import FaultBook
from .fence import Fence, build_fence, validate_fence
from .flavour import Flavour, Mode
from .geo import LocalFrame
from .mission import MissionItem, Upload
from .signing import OK, SigningState
from .world import AnyBody, Phase, Rover

log = logging.getLogger(__name__)

M = mavlink2
MAX_RATE_HZ = 50.0
FORCE_MAGIC = 21196.0
MISSION_REJECTED_TEXT = "Mission rejected: failed feasibility check"  # reject_mission fault
GEOFENCE_BREACH_TEXT = "Geofence breach"
FENCE = M.MAV_MISSION_TYPE_FENCE

STREAM_DEFAULTS_HZ: dict[int, float] = {
    M.MAVLINK_MSG_ID_HEARTBEAT: 1.0,
    M.MAVLINK_MSG_ID_SYS_STATUS: 1.0,
    M.MAVLINK_MSG_ID_GPS_RAW_INT: 1.0,
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 10.0,  # replaced by the fleet's position_hz
    M.MAVLINK_MSG_ID_MISSION_CURRENT: 1.0,
    M.MAVLINK_MSG_ID_BATTERY_STATUS: 1.0,
    M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 1.0,
    M.MAVLINK_MSG_ID_HOME_POSITION: 0.5,
}
STREAMABLE = set(STREAM_DEFAULTS_HZ) | {
    M.MAVLINK_MSG_ID_ATTITUDE, M.MAVLINK_MSG_ID_VFR_HUD, M.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
    M.MAVLINK_MSG_ID_SYSTEM_TIME, M.MAVLINK_MSG_ID_FENCE_STATUS,
}
REQUESTABLE = STREAMABLE | {M.MAVLINK_MSG_ID_AUTOPILOT_VERSION}

_SENSORS = (
    M.MAV_SYS_STATUS_SENSOR_3D_GYRO | M.MAV_SYS_STATUS_SENSOR_3D_ACCEL | M.MAV_SYS_STATUS_SENSOR_3D_MAG
    | M.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE | M.MAV_SYS_STATUS_SENSOR_GPS | M.MAV_SYS_STATUS_AHRS
    | M.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS | M.MAV_SYS_STATUS_SENSOR_BATTERY
)
_CAPABILITIES = (
    M.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT | M.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    | M.MAV_PROTOCOL_CAPABILITY_MISSION_INT | M.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | M.MAV_PROTOCOL_CAPABILITY_MAVLINK2
)


class Clock(Protocol):
    @property
    def sim_time(self) -> float: ...

    def wall(self) -> float: ...

    def stream_time(self) -> float:
        """The clock of the telemetry streams: simulated seconds, never slower than wall seconds."""
        ...


class Link(Protocol):
    def send(self, vehicle: SimVehicle, data: bytes, addr: Any | None) -> None: ...


@dataclass
class Command:
    """COMMAND_LONG and COMMAND_INT in one shape; lat/lon in degrees (NaN = not given)."""

    command: int
    p: tuple[float, float, float, float]
    lat: float
    lon: float
    alt: float
    frame: int | None  # None for COMMAND_LONG
    src: tuple[int, int]


class SimVehicle:
    """One simulated autopilot. Feed it messages with ``handle``; ``update`` runs it one
    simulated step; ``service`` sends the telemetry due and runs protocol timers."""

    def __init__(
        self,
        spec: VehicleSpec,
        body: AnyBody,
        flavour: Flavour,
        frame: LocalFrame,
        clock: Clock,
        faults: FaultBook,
        position_hz: float = 10.0,
    ) -> None:
        self.spec = spec
        self.id = spec.id
        self.sysid = spec.sysid
        self.uid = zlib.crc32(spec.id.encode())  # AUTOPILOT_VERSION's uid: one per vehicle, not per sysid
        self.compid = spec.compid
        self.body = body
        self.rover = body if isinstance(body, Rover) else None  # the body again, when it is a rover
        self.is_rover = self.rover is not None
        self.flavour = flavour
        self.frame = frame
        self.clock = clock
        self.faults = faults
        self.link: Link | None = None
        self.mav = M.MAVLink(None, srcSystem=spec.sysid, srcComponent=spec.compid)
        self.signing = SigningState(self.mav)  # no key: unsigned (set_signing_key / SETUP_SIGNING)

        self.armed = isinstance(body, Rover) and body.phase is Phase.AIR  # a rover placed in the air flies
        self.mode = Mode.HOLD
        self.paused = False
        self.home = (body.position[0], body.position[1], 0.0)
        self.mission: list[MissionItem] = []
        self.mission_version = 0
        self.current = 0
        self.finished = False
        self._item_key: tuple[int, int] | None = None
        self._hold_until: float | None = None
        self._rtl_phase = 0
        self._takeoff_pending = False
        self._drive_off_state = 0  # drive_off fault: 1 driving on, 2 stopped off its mission (to set_current)
        self._disarm_at: float | None = None
        self._ended_at_landing = False  # ArduCopter: its mission ended at a NAV_LAND that more items follow
        self._upload: Upload | None = None
        self._last_upload: tuple[tuple[int, int], int, int] | None = None  # partner, count, mission_type
        self.statustexts: list[tuple[float, int, str]] = []
        # geofence (mission_type FENCE) and link loss (no GCS heartbeat while armed)
        self.fence_items: list[MissionItem] = []
        self.fence = Fence()
        self.fence_breach = 0  # FENCE_BREACH of the current breach, 0 = inside
        self.fence_breach_count = 0
        self._fence_loaded = False  # a fence was uploaded once (Flavour.fence_load_time)
        self._fence_loaded_at = 0.0  # sim time: the mission mode refused "for now" until then
        self._fence_breach_time = 0
        self.gcs_heard: float | None = None  # wall time of the last GCS heartbeat
        self.link_lost = False
        self.commands_seen = 0
        self.ignored_other_target = 0

        self._geo: tuple[float, float, float] | None = None
        self._home_geo: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
        self._geo_key: object = None

        now = clock.stream_time()
        phase = (spec.sysid * 0.6180339887) % 1.0  # spread the vehicles' streams over time
        self.streams: dict[int, list[float]] = {}
        for msgid, hz in STREAM_DEFAULTS_HZ.items():
            if msgid == M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT:
                hz = position_hz
            self.streams[msgid] = [1.0 / hz, now + phase / hz]
        self._default_intervals = {k: v[0] for k, v in self.streams.items()}
        self.next_due = min(v[1] for v in self.streams.values())
        self._handlers: dict[str, Callable[[Any, Any], None]] = {
            "COMMAND_LONG": self._on_command_long,
            "COMMAND_INT": self._on_command_int,
            "SET_MODE": self._on_set_mode,
            "MISSION_COUNT": self._on_mission_count,
            "MISSION_ITEM_INT": self._on_mission_item,
            "MISSION_ITEM": self._on_mission_item,
            "MISSION_REQUEST_LIST": self._on_mission_request_list,
            "MISSION_REQUEST_INT": self._on_mission_request,
            "MISSION_REQUEST": self._on_mission_request,
            "MISSION_ACK": self._on_mission_ack,
            "MISSION_CLEAR_ALL": self._on_mission_clear_all,
            "MISSION_SET_CURRENT": self._on_mission_set_current,
            "PARAM_REQUEST_LIST": self._on_param_request_list,
            "PARAM_REQUEST_READ": self._on_param_request_read,
            "PARAM_SET": self._on_param_set,
            "PING": self._on_ping,
            "HEARTBEAT": self._on_gcs_heartbeat,
            "TIMESYNC": self._on_timesync,
            "SETUP_SIGNING": self._on_setup_signing,
        }
        self._apply_speed_params()

    # ======================================================================================
    # output
    # ======================================================================================
    def _send(self, msg: Any, addr: Any | None = None) -> None:
        if self.link is None:
            return
        if self.signing.key is not None:
            self.signing.stamp()
        data = msg.pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) & 0xFF
        self.link.send(self, data, addr)

    def statustext(self, text: str, severity: int = M.MAV_SEVERITY_INFO) -> None:
        self.statustexts.append((self.clock.sim_time, severity, text))
        del self.statustexts[:-200]
        log.info("%s: %s", self.id, text)
        self._send(self.mav.statustext_encode(severity, text.encode()[:50]))

    # ======================================================================================
    # input
    # ======================================================================================
    def handle(self, msg: Any, addr: Any = None) -> None:
        """One decoded message from a ground station (any target; others' messages are ignored).
        With a signing key, unsigned (but RADIO_STATUS), wrongly signed and replayed messages are
        dropped here (counted in ``signing.rejected``)."""
        if self.signing.key is not None and self.signing.check(msg.get_msgbuf()) != OK:
            return
        handler = self._handlers.get(msg.get_type())
        if handler is not None:
            handler(msg, addr)

    def _for_me(self, msg: Any, broadcast_ok: bool = True) -> bool:
        ts = msg.target_system
        tc = getattr(msg, "target_component", 0)
        ok = (ts == self.sysid or (broadcast_ok and ts == 0)) and tc in (0, self.compid)
        if not ok:
            self.ignored_other_target += 1
        return ok

    # ======================================================================================
    # signing
    # ======================================================================================
    def set_signing_key(self, key: bytes | None) -> None:
        """Sign and verify with ``key`` (32 bytes) from now on; None or all zeros: unsigned."""
        self.signing.set_key(key)

    def _on_setup_signing(self, msg: Any, addr: Any) -> None:
        if not self._for_me(msg, broadcast_ok=False):
            return
        if self.armed:
            self.statustext("Signing setup refused: vehicle is armed", M.MAV_SEVERITY_WARNING)
            return
        key = bytes(msg.secret_key)
        self.signing.set_key(key, msg.initial_timestamp)
        self.statustext("Signing enabled" if self.signing.key is not None else "Signing disabled")

    # ======================================================================================
    # commands
    # ======================================================================================
    def _on_command_long(self, msg: Any, addr: Any) -> None:
        if not self._for_me(msg):
            return
        cmd = Command(msg.command, (msg.param1, msg.param2, msg.param3, msg.param4),
                      msg.param5, msg.param6, msg.param7, None, (msg.get_srcSystem(), msg.get_srcComponent()))
        self._run_command(cmd, addr)

    def _on_command_int(self, msg: Any, addr: Any) -> None:
        if not self._for_me(msg):
            return
        lat = msg.x / 1e7 if msg.x != 0x7FFFFFFF else math.nan
        lon = msg.y / 1e7 if msg.y != 0x7FFFFFFF else math.nan
        cmd = Command(msg.command, (msg.param1, msg.param2, msg.param3, msg.param4), lat, lon, msg.z,
                      msg.frame, (msg.get_srcSystem(), msg.get_srcComponent()))
        self._run_command(cmd, addr)

    def _run_command(self, cmd: Command, addr: Any) -> None:
        self.commands_seen += 1
        handler = _COMMANDS.get(cmd.command)
        after: Callable[[], None] | None = None
        if handler is None:
            result = M.MAV_RESULT_UNSUPPORTED
        else:
            out = handler(self, cmd)
            result, after = out if isinstance(out, tuple) else (out, None)
        self._send(self.mav.command_ack_encode(cmd.command, result, 0, 0, cmd.src[0], cmd.src[1]), addr)
        if after is not None:
            after()

    def _cmd_arm(self, cmd: Command) -> int:
        force = abs(cmd.p[1] - FORCE_MAGIC) < 0.5
        if cmd.p[0] >= 0.5:
            return self.arm()
        return self.disarm(force)

    def arm(self) -> int:
        """Arm (MAV_RESULT)."""
        if self.armed:
            return M.MAV_RESULT_ACCEPTED
        if self.faults.refuses_arm(self.id, self.clock.sim_time):
            self.statustext("Arming denied: preflight check failed", M.MAV_SEVERITY_CRITICAL)
            return M.MAV_RESULT_DENIED
        if self.rover is not None and self.rover.battery <= 0.0:
            self.statustext("Arming denied: battery empty", M.MAV_SEVERITY_CRITICAL)
            return M.MAV_RESULT_DENIED
        if self.faults.no_gps(self.id, self.clock.sim_time):
            self.statustext("Arming denied: no GPS fix", M.MAV_SEVERITY_CRITICAL)
            return M.MAV_RESULT_DENIED
        if self.faults.unhealthy(self.id, self.clock.sim_time):
            self.statustext("Arming denied: compass unhealthy", M.MAV_SEVERITY_CRITICAL)
            return M.MAV_RESULT_DENIED
        self.armed = True
        self._disarm_at = None
        self.home = (self.body.position[0], self.body.position[1], 0.0)
        self.statustext("Armed")
        self._item_key = None
        self._emit_heartbeat_now()
        return M.MAV_RESULT_ACCEPTED

    def disarm(self, force: bool = False) -> int:
        if not self.armed:
            return M.MAV_RESULT_ACCEPTED
        if self.rover is not None and self.rover.phase is Phase.AIR:
            self.statustext("Disarming denied: in air", M.MAV_SEVERITY_WARNING)
            return M.MAV_RESULT_DENIED
        self.armed = False
        self._disarm_at = None
        self.body.hold()
        self.statustext("Disarmed")
        self._emit_heartbeat_now()
        return M.MAV_RESULT_ACCEPTED

    def _cmd_takeoff(self, cmd: Command) -> int:
        if self.rover is None:
            return M.MAV_RESULT_UNSUPPORTED
        if not self.armed:
            self.statustext("Takeoff denied: disarmed", M.MAV_SEVERITY_WARNING)
            return M.MAV_RESULT_DENIED
        if self.rover.battery <= 0.0:
            return M.MAV_RESULT_DENIED
        if self.flavour.px4:  # PX4: param7 is AMSL, NaN = MIS_TAKEOFF_ALT above home
            alt = self.flavour.takeoff_alt() if not math.isfinite(cmd.alt) else cmd.alt - self.frame.alt0
        else:  # ArduPilot: param7 is the height above home
            alt = cmd.alt if math.isfinite(cmd.alt) and cmd.alt > 0 else self.flavour.takeoff_alt()
        self._start_takeoff(max(alt, 0.5))
        self._set_mode_raw(Mode.TAKEOFF)
        return M.MAV_RESULT_ACCEPTED

    def _start_takeoff(self, alt: float) -> None:
        body = self.body
        assert isinstance(body, Rover)
        self._takeoff_pending = False
        if body.phase is Phase.AIR:
            x, y, _ = body.position
            body.goto(x, y, alt)
        else:
            body.takeoff(alt)

    def _cmd_land(self, cmd: Command) -> int:
        rover = self.rover
        if rover is None:
            self.body.hold()
            self._set_mode_raw(Mode.HOLD)
            return M.MAV_RESULT_ACCEPTED
        self._set_mode_raw(Mode.LAND)
        if math.isfinite(cmd.lat) and math.isfinite(cmd.lon) and not (cmd.lat == 0 and cmd.lon == 0):
            x, y, _ = self.frame.to_enu(cmd.lat, cmd.lon, self.frame.alt0)
            rover.land(x, y)
        else:
            rover.land()
        return M.MAV_RESULT_ACCEPTED

    def _cmd_rtl(self, cmd: Command) -> int:
        return self.set_mode(Mode.RTL)

    def _cmd_set_mode(self, cmd: Command) -> int:
        mode = self.flavour.mode_from_command(cmd.p[1], cmd.p[2])
        if mode is None:
            self.statustext(f"Mode {int(cmd.p[1])}/{int(cmd.p[2])} not supported", M.MAV_SEVERITY_WARNING)
            return M.MAV_RESULT_DENIED
        return self.set_mode(mode)

    def _on_set_mode(self, msg: Any, addr: Any) -> None:
        if msg.target_system != self.sysid:
            return
        mode = self.flavour.mode_from_set_mode(msg.custom_mode)
        if mode is not None:
            self.set_mode(mode)

    def _cmd_mission_start(self, cmd: Command) -> int:
        if not self._has_mission():
            self.statustext("Mission start denied: no mission", M.MAV_SEVERITY_WARNING)
            return M.MAV_RESULT_DENIED
        first = int(cmd.p[0]) if math.isfinite(cmd.p[0]) else 0
        if 0 < first < len(self.mission):
            self.current = first
            self.finished = False
        return self.set_mode(Mode.MISSION)

    def _cmd_reposition(self, cmd: Command) -> int:
        if not self.armed:
            return M.MAV_RESULT_DENIED
        here = self.body.position
        if math.isfinite(cmd.lat) and math.isfinite(cmd.lon):
            x, y, _ = self.frame.to_enu(cmd.lat, cmd.lon, self.frame.alt0)
        else:
            x, y = here[0], here[1]
        z = here[2]
        if math.isfinite(cmd.alt):  # PX4 takes it AMSL whatever the frame (as PX4 1.18 does)
            relative = cmd.frame in ms.FRAME_RELATIVE and not self.flavour.px4
            z = self.home[2] + cmd.alt if relative else cmd.alt - self.frame.alt0
        speed = cmd.p[0] if math.isfinite(cmd.p[0]) and cmd.p[0] > 0 else None
        if not self.body.goto(x, y, max(z, 0.0), speed) and self.is_rover:
            return M.MAV_RESULT_DENIED
        self._set_mode_raw(Mode.GUIDED)
        return M.MAV_RESULT_ACCEPTED

    def _cmd_set_current(self, cmd: Command) -> int:
        seq = int(cmd.p[0]) if math.isfinite(cmd.p[0]) else -1
        if seq == -1 and cmd.p[1] >= 0.5:
            seq = 1 if self.flavour.home_is_item0 else 0
        if not self.set_current(seq):
            return M.MAV_RESULT_DENIED
        return M.MAV_RESULT_ACCEPTED

    def _cmd_pause_continue(self, cmd: Command) -> int:
        if cmd.p[0] < 0.5:  # pause
            self.paused = True
            self.body.hold()
            self.statustext("Paused")
            return M.MAV_RESULT_ACCEPTED
        if self.mode is not Mode.MISSION:
            return M.MAV_RESULT_DENIED
        self.paused = False
        self._item_key = None
        self.statustext("Continuing")
        return M.MAV_RESULT_ACCEPTED

    def _cmd_change_speed(self, cmd: Command) -> int:
        if math.isfinite(cmd.p[1]) and cmd.p[1] > 0:
            self.body.set_speed(cmd.p[1])
            return M.MAV_RESULT_ACCEPTED
        return M.MAV_RESULT_DENIED if cmd.p[1] != -1 else M.MAV_RESULT_ACCEPTED

    def _cmd_set_home(self, cmd: Command) -> int:
        if cmd.p[0] >= 0.5 or not (math.isfinite(cmd.lat) and math.isfinite(cmd.lon)):
            self.home = (self.body.position[0], self.body.position[1], 0.0)
        else:
            alt = cmd.alt if math.isfinite(cmd.alt) else self.frame.alt0
            x, y, z = self.frame.to_enu(cmd.lat, cmd.lon, alt)
            self.home = (x, y, max(z, 0.0))
        return M.MAV_RESULT_ACCEPTED

    def _cmd_battery_reset(self, cmd: Command) -> int:
        """MAV_CMD_BATTERY_RESET (param2: the percentage now left, default 100): a battery swapped
        (or charged) on the carrier's deck. Refused in the air, armed, or off the deck."""
        rover = self.rover
        if rover is None:
            return M.MAV_RESULT_UNSUPPORTED
        if self.armed or not rover.loaded:
            self.statustext("Battery swap denied: not disarmed on the deck", M.MAV_SEVERITY_WARNING)
            return M.MAV_RESULT_DENIED
        pct = cmd.p[1] if math.isfinite(cmd.p[1]) and 0.0 < cmd.p[1] <= 100.0 else 100.0
        rover.battery = pct / 100.0
        self.statustext(f"Battery swapped: {pct:.0f}%")
        return M.MAV_RESULT_ACCEPTED

    def _cmd_request_message(self, cmd: Command) -> int | tuple[int, Callable[[], None]]:
        msgid = int(cmd.p[0]) if math.isfinite(cmd.p[0]) else -1
        if msgid not in REQUESTABLE:
            return M.MAV_RESULT_UNSUPPORTED
        return M.MAV_RESULT_ACCEPTED, lambda: self._emit(msgid)

    def _cmd_request_capabilities(self, cmd: Command) -> tuple[int, Callable[[], None]]:
        return M.MAV_RESULT_ACCEPTED, lambda: self._emit(M.MAVLINK_MSG_ID_AUTOPILOT_VERSION)

    def _cmd_set_interval(self, cmd: Command) -> int:
        msgid = int(cmd.p[0]) if math.isfinite(cmd.p[0]) else -1
        if msgid not in STREAMABLE:
            return M.MAV_RESULT_UNSUPPORTED
        us = cmd.p[1]
        now = self.clock.stream_time()
        if us == -1:
            self.streams.pop(msgid, None)
        elif us == 0:
            if msgid in self._default_intervals:
                self.streams[msgid] = [self._default_intervals[msgid], now]
            else:
                self.streams.pop(msgid, None)
        elif us > 0:
            interval = max(us / 1e6, 1.0 / MAX_RATE_HZ)
            self.streams[msgid] = [interval, now]
        else:
            return M.MAV_RESULT_DENIED
        self.next_due = min((v[1] for v in self.streams.values()), default=math.inf)
        return M.MAV_RESULT_ACCEPTED

    def _cmd_get_interval(self, cmd: Command) -> tuple[int, Callable[[], None]]:
        msgid = int(cmd.p[0]) if math.isfinite(cmd.p[0]) else -1
        st = self.streams.get(msgid)
        us = int(st[0] * 1e6) if st else (-1 if msgid in STREAMABLE else 0)
        return M.MAV_RESULT_ACCEPTED, lambda: self._send(self.mav.message_interval_encode(msgid, us))

    # ======================================================================================
    # modes
    # ======================================================================================
    def set_mode(self, mode: Mode) -> int:
        """Switch flight mode as DO_SET_MODE would (MAV_RESULT)."""
        if mode is Mode.MISSION:
            if not self._has_mission():
                self.statustext("Mission mode denied: no mission", M.MAV_SEVERITY_WARNING)
                return M.MAV_RESULT_DENIED
            if self.clock.sim_time < self._fence_loaded_at:  # the first fence still being loaded
                return M.MAV_RESULT_TEMPORARILY_REJECTED
            if self.finished:
                self.current = self._first_item()
                self.finished = False
            if self.flavour.home_is_item0 and self.current == 0:
                self.current = 1
            self.paused = False
            self._item_key = None
        elif mode in (Mode.HOLD, Mode.MANUAL, Mode.GUIDED):
            self.body.hold()
        elif mode is Mode.TAKEOFF:
            if not self.is_rover:
                return M.MAV_RESULT_DENIED
            if self.armed:
                self._start_takeoff(self.flavour.takeoff_alt())
            else:
                self._takeoff_pending = True
        elif mode is Mode.RTL:
            self._rtl_phase = 0
        elif mode is Mode.LAND:
            if self.rover is not None:
                self.rover.land()
            else:
                self.body.hold()
        self._set_mode_raw(mode)
        return M.MAV_RESULT_ACCEPTED

    def _set_mode_raw(self, mode: Mode) -> None:
        if mode is not self.mode:
            self.mode = mode
            if mode is Mode.RTL:
                self._rtl_phase = 0
            self._emit_heartbeat_now()

    def _rtl_step(self) -> bool:
        """Advance a return to launch; True once done (rover landed / carrier home)."""
        body = self.body
        hx, hy, hz = self.home
        if not isinstance(body, Rover):
            if self._rtl_phase == 0:
                body.goto(hx, hy, 0.0)
                self._rtl_phase = 1
                return False
            return body.arrived
        if body.phase is not Phase.AIR:
            return self._rtl_phase > 0
        if self._rtl_phase == 0:
            alt = max(body.position[2], hz + self.flavour.rtl_alt())
            body.goto(hx, hy, alt)
            self._rtl_phase = 1
        elif self._rtl_phase == 1 and body.arrived:
            body.land()
            self._rtl_phase = 2
        return False

    # ======================================================================================
    # simulation step (simulated time)
    # ======================================================================================
    def update(self, t: float) -> None:
        rover = self.rover
        if rover is not None and len(self.faults):
            level = self.faults.battery_level(self.id, t)
            if level is not None and rover.battery > level:
                rover.battery = level
        if self.armed and (self.fence.has_zones or self.flavour.fence(False)[2] is not None):
            self._check_fence(t)
        if rover is not None and rover.events:
            self._on_body_events(t)
        if self._disarm_at is not None and t >= self._disarm_at:
            self._disarm_at = None
            if self.armed and rover is not None and rover.on_ground:
                self.armed = False
                self.statustext("Disarmed (landed)")
                self._emit_heartbeat_now()
                if self._ended_at_landing and self.mode is Mode.MISSION and self._has_mission():
                    self._restart_mission()
                self._ended_at_landing = False
        if not self.armed:
            return
        if rover is None and (self._drive_off_state or self.faults.drives_off(self.id, t)):
            self._drive_off(t)
            return
        mode = self.mode
        if mode is Mode.MISSION:
            if not self.paused:
                self._run_mission(t)
        elif mode is Mode.TAKEOFF:
            if self._takeoff_pending:
                self._start_takeoff(self.flavour.takeoff_alt())
            elif rover is not None and rover.arrived and rover.phase is Phase.AIR:
                self.statustext("Takeoff complete")
                self._set_mode_raw(Mode.HOLD if self.flavour.px4 else Mode.GUIDED)
        elif mode is Mode.RTL:
            if self._rtl_step() and not self.is_rover:
                self._set_mode_raw(Mode.HOLD)

    def _drive_off(self, t: float) -> None:
        """The ``drive_off`` fault: on along the heading while it lasts; then a stop where it is,
        holding there until a current item is set again (:meth:`set_current`)."""
        body = self.body
        if self.faults.drives_off(self.id, t):
            self._drive_off_state = 1
            x, y, _z = body.position
            body.target = (x + 10.0 * math.cos(body.heading), y + 10.0 * math.sin(body.heading), 0.0)
        elif self._drive_off_state == 1:
            body.target = None  # the fault is over: it brakes to a stop where it is
            self._drive_off_state = 2

    # -- geofence and link loss ----------------------------------------------------------------
    def _check_fence(self, t: float) -> None:
        polygon, action, alt_max = self.flavour.fence(self.fence.has_zones)
        if action is None:
            return
        x, y, z = self.body.position
        breach = 0
        if polygon and self.fence.outside(x, y):
            breach = M.FENCE_BREACH_BOUNDARY
        elif alt_max is not None and z - self.home[2] > alt_max:
            breach = M.FENCE_BREACH_MAXALT
        if breach == self.fence_breach:
            return
        self.fence_breach = breach
        if not breach:
            self._emit(M.MAVLINK_MSG_ID_FENCE_STATUS)
            return
        self.fence_breach_count += 1
        self._fence_breach_time = int(t * 1000)
        what = "altitude" if breach == M.FENCE_BREACH_MAXALT else "boundary"
        self._emit(M.MAVLINK_MSG_ID_FENCE_STATUS)  # first: a ground station learns the breach type
        self.statustext(f"{GEOFENCE_BREACH_TEXT}: {what}, {action}", M.MAV_SEVERITY_CRITICAL)
        self._failsafe_action(action)

    def _failsafe_action(self, action: str) -> None:
        if action == "hold":
            self.set_mode(Mode.HOLD)
        elif action == "rtl":
            self.set_mode(Mode.RTL)
        elif action == "land":
            self.set_mode(Mode.LAND)

    def _on_gcs_heartbeat(self, msg: Any, addr: Any) -> None:
        if msg.type != M.MAV_TYPE_GCS:
            return
        self.gcs_heard = self.clock.wall()
        if self.link_lost:
            self.link_lost = False
            self.statustext("GCS link regained", M.MAV_SEVERITY_INFO)

    def _check_link(self, now: float) -> None:
        """The link-loss failsafe (wall time, like the GCS's 1 Hz heartbeat it watches)."""
        if self.link_lost or self.gcs_heard is None or not self.armed:
            return
        action, timeout = self.flavour.link_loss(self.mode is Mode.MISSION)
        if now - self.gcs_heard < max(timeout, 0.1):
            return
        self.link_lost = True
        if action is None:
            return
        self.statustext(f"Failsafe: GCS link lost, {action}", M.MAV_SEVERITY_CRITICAL)
        if action == "land" and self.rover is None:
            action = "hold"  # a ground carrier stops
        self._failsafe_action(action)

    def _on_body_events(self, t: float) -> None:
        body = self.body
        assert isinstance(body, Rover)
        events, body.events = body.events, []
        for ev in events:
            if ev == "takeoff":
                self._disarm_at = None
                self._ended_at_landing = False
            elif ev == "touchdown":
                self._emit(M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE)  # the landed state as it changes
                self.statustext("Landed on carrier" if body.loaded else "Landed")
                delay = self.flavour.disarm_delay()
                if self.armed and delay >= 0 and not self._landing_mid_mission():
                    self._disarm_at = t + delay
                if self.armed and self.flavour.landing_ends_mission and self._landing_mid_mission_items():
                    self.finished = True  # ArduCopter: the items after a mission's landing never run
                    self._ended_at_landing = True
            elif ev == "battery_empty":
                self.statustext("Battery empty: landing", M.MAV_SEVERITY_CRITICAL)
                if body.phase is Phase.AIR:
                    self._set_mode_raw(Mode.LAND)

    def _landing_mid_mission_items(self) -> bool:
        """The current item is a NAV_LAND of the mission that more items follow."""
        cur = self.current
        return (self.mode is Mode.MISSION and cur + 1 < len(self.mission)
                and self.mission[cur].command == ms.NAV_LAND)

    def _restart_mission(self) -> None:
        """ArduCopter, disarmed by a mission's landing: the mission starts over at its first item
        (not flown: the vehicle is disarmed), as "Mission: 1 Takeoff" tells on the firmware."""
        self.current = self._first_item()
        self.finished = False
        self._item_key = None
        self.statustext(f"Mission: {self.current} restarted")
        self._emit(M.MAVLINK_MSG_ID_MISSION_CURRENT)

    def _landing_mid_mission(self) -> bool:
        """A NAV_LAND of the mission that more items follow (a task worked landed, then a
        NAV_DELAY and a NAV_TAKEOFF): the vehicle stays armed on the ground, as in a mission -
        on PX4; ArduCopter disarms there all the same (:attr:`Flavour.landing_ends_mission`)."""
        return self._landing_mid_mission_items() and not self.flavour.landing_ends_mission

    # -- mission executor ------------------------------------------------------------------
    def _has_mission(self) -> bool:
        return len(self.mission) > (1 if self.flavour.home_is_item0 else 0)

    def _first_item(self) -> int:
        return 1 if self.flavour.home_is_item0 and len(self.mission) > 1 else 0

    def _run_mission(self, t: float) -> None:
        for _ in range(len(self.mission) + 1):
            if self.finished or not self.mission or self.current >= len(self.mission):
                return
            seq = self.current
            item = self.mission[seq]
            key = (self.mission_version, seq)
            if self._item_key != key:
                self._item_key = key
                self._hold_until = None
                self._rtl_phase = 0
                done = self._start_item(item)
            else:
                done = self._check_item(item, t)
            if not done:
                return
            self._item_reached(seq)

    def _target(self, item: MissionItem) -> tuple[float, float, float]:
        return ms.item_target(item, self.frame, self.home[2], self.body.position)

    def _start_item(self, item: MissionItem) -> bool:
        cmd = item.command
        body = self.body
        if cmd == ms.DO_CHANGE_SPEED:
            if math.isfinite(item.param2) and item.param2 > 0:
                body.set_speed(item.param2)
            return True
        if cmd == ms.NAV_RTL:
            self._rtl_phase = 0
            return self._rtl_step()
        if cmd == ms.NAV_DELAY:  # wait where it is: hovering, or landed (a task worked on the ground)
            return False
        if cmd == ms.NAV_TAKEOFF:
            if not self.is_rover:
                return True
            _, _, z = self._target(item)
            if not math.isfinite(item.z):
                z = self.home[2] + self.flavour.takeoff_alt()
            self._start_takeoff(max(z, 0.5))
            return False
        if cmd == ms.NAV_LAND:
            if not isinstance(body, Rover):
                body.hold()
                return False
            if body.phase is not Phase.AIR:
                return True
            if item.has_latlon():
                x, y, _ = self._target(item)
                body.land(x, y)
            else:
                body.land()
            return False
        # NAV_WAYPOINT, NAV_LOITER_TIME, NAV_LOITER_UNLIM
        x, y, z = self._target(item)
        if isinstance(body, Rover) and self._flown_through(item):
            ok = body.goto(x, y, z, through=True)
        else:
            ok = body.goto(x, y, z)
        if not ok:
            self.statustext(f"Mission item {item.seq}: cannot fly there", M.MAV_SEVERITY_WARNING)
        return False

    def _flown_through(self, item: MissionItem) -> bool:
        """A multirotor flies through a waypoint with no hold that another waypoint follows, as
        the autopilots do (PX4, ArduCopter); it stops at the last one."""
        nxt = item.seq + 1
        return (item.command == ms.NAV_WAYPOINT and not (math.isfinite(item.param1) and item.param1 > 0)
                and nxt < len(self.mission) and self.mission[nxt].command == ms.NAV_WAYPOINT)

    def _check_item(self, item: MissionItem, t: float) -> bool:
        cmd = item.command
        body = self.body
        if isinstance(body, Rover) and body.passed and cmd == ms.NAV_WAYPOINT:
            body.passed = False
            return True
        if cmd == ms.NAV_TAKEOFF:
            return isinstance(body, Rover) and body.arrived and body.phase is Phase.AIR
        if cmd == ms.NAV_LAND:
            return body.on_ground if isinstance(body, Rover) else body.arrived
        if cmd == ms.NAV_RTL:
            return self._rtl_step()
        if cmd == ms.NAV_LOITER_UNLIM:
            return False
        if cmd != ms.NAV_DELAY and not body.arrived:
            return False
        if self._hold_until is None:
            hold = item.param1 if math.isfinite(item.param1) and item.param1 > 0 else 0.0
            self._hold_until = t + hold
        return t >= self._hold_until - 1e-9

    def _item_reached(self, seq: int) -> None:
        self._send(self.mav.mission_item_reached_encode(seq))
        if seq + 1 < len(self.mission):
            self.current = seq + 1
        else:
            self.finished = True
            if self.rover is not None and self.rover.phase is Phase.AIR:
                self.rover.hold()
            self.statustext("Mission finished")
        self._emit(M.MAVLINK_MSG_ID_MISSION_CURRENT)

    def set_current(self, seq: int) -> bool:
        """Make ``seq`` the current mission item (MISSION_SET_CURRENT)."""
        if not 0 <= seq < len(self.mission) or (self.flavour.home_is_item0 and seq == 0):
            return False
        self.current = seq
        self.finished = False
        self._item_key = None
        self._drive_off_state = 0
        self._emit(M.MAVLINK_MSG_ID_MISSION_CURRENT)
        return True

    def _on_mission_set_current(self, msg: Any, addr: Any) -> None:
        if not self._for_me(msg, broadcast_ok=False):
            return
        if not self.set_current(msg.seq):
            self.statustext(f"Mission item {msg.seq} does not exist", M.MAV_SEVERITY_WARNING)
            self._emit(M.MAVLINK_MSG_ID_MISSION_CURRENT)

    # ======================================================================================
    # mission protocol
    # ======================================================================================
    def _mission_ack(self, partner: tuple[int, int], addr: Any, result: int, mission_type: int = 0) -> None:
        self._send(self.mav.mission_ack_encode(partner[0], partner[1], result, mission_type), addr)

    def _request_item(self, up: Upload) -> None:
        enc = self.mav.mission_request_int_encode if up.int_mode else self.mav.mission_request_encode
        self._send(enc(up.partner[0], up.partner[1], up.expected, up.mission_type), up.addr)
        up.deadline = self.clock.wall() + ms.ITEM_TIMEOUT

    def _on_mission_count(self, msg: Any, addr: Any) -> None:
        if not self._for_me(msg, broadcast_ok=False):
            return
        partner = (msg.get_srcSystem(), msg.get_srcComponent())
        mtype = getattr(msg, "mission_type", 0)
        if mtype not in (M.MAV_MISSION_TYPE_MISSION, FENCE):
            self._mission_ack(partner, addr, M.MAV_MISSION_UNSUPPORTED, mtype)
            return
        up = self._upload
        if up is not None and up.partner != partner:
            self._mission_ack(partner, addr, M.MAV_MISSION_DENIED, mtype)
            return
        if self.faults.rejects_mission(self.id, self.clock.sim_time):  # reason first, then the ACK
            self._upload = None
            self.statustext(MISSION_REJECTED_TEXT, M.MAV_SEVERITY_CRITICAL)
            self._mission_ack(partner, addr, M.MAV_MISSION_DENIED, mtype)
            return
        if msg.count == 0:
            self._upload = None
            if mtype == FENCE:
                self._replace_fence([])
            else:
                self._replace_mission([])
            self._mission_ack(partner, addr, M.MAV_MISSION_ACCEPTED, mtype)
            return
        if msg.count > ms.MAX_ITEMS:
            self._upload = None
            self._mission_ack(partner, addr, M.MAV_MISSION_NO_SPACE, mtype)
            return
        self._upload = Upload(partner=partner, addr=addr, count=msg.count, mission_type=mtype)
        self._request_item(self._upload)

    def _on_mission_item(self, msg: Any, addr: Any) -> None:
        if not self._for_me(msg, broadcast_ok=False):
            return
        partner = (msg.get_srcSystem(), msg.get_srcComponent())
        up = self._upload
        if up is None or up.partner != partner:
            last = self._last_upload
            if last is not None and last[0] == partner and msg.seq == last[1] - 1:
                self._mission_ack(partner, addr, M.MAV_MISSION_ACCEPTED, last[2])  # our ACK was lost
            else:
                log.debug("%s: mission item %d with no upload in progress, ignored", self.id, msg.seq)
            return
        up.addr = addr
        if getattr(msg, "mission_type", 0) != up.mission_type:
            self._upload = None
            self._mission_ack(partner, addr, M.MAV_MISSION_ERROR, up.mission_type)
            return
        if msg.seq < up.expected:  # a duplicate: our request crossed it; ask again for the one we need
            self._request_item(up)
            return
        if msg.seq > up.expected:
            self._upload = None
            self.statustext(f"Mission upload: got item {msg.seq}, expected {up.expected}",
                            M.MAV_SEVERITY_WARNING)
            self._mission_ack(partner, addr, M.MAV_MISSION_INVALID_SEQUENCE, up.mission_type)
            return
        if msg.get_type() == "MISSION_ITEM":
            up.int_mode = False
        item = MissionItem.from_msg(msg)
        if up.mission_type == FENCE:
            result = M.MAV_MISSION_ACCEPTED  # checked whole, at the end
        else:
            result = ms.validate(item, home_item=self.flavour.home_is_item0 and item.seq == 0)
        if result != M.MAV_MISSION_ACCEPTED:
            self._upload = None
            self._mission_ack(partner, addr, result, up.mission_type)
            return
        up.items.append(item)
        up.retries = 0
        if up.expected < up.count:
            self._request_item(up)
            return
        self._upload = None
        if up.mission_type == FENCE:
            result = validate_fence(up.items)
            if result != M.MAV_MISSION_ACCEPTED:
                self._mission_ack(partner, addr, result, up.mission_type)
                return
            self._replace_fence(up.items)
        else:
            self._replace_mission(up.items)
        self._last_upload = (partner, up.count, up.mission_type)
        self._mission_ack(partner, addr, M.MAV_MISSION_ACCEPTED, up.mission_type)

    def _replace_mission(self, items: list[MissionItem]) -> None:
        self.mission = list(items)
        self.mission_version += 1
        self.finished = False
        self._item_key = None
        flagged = [i.seq for i in items if i.current]
        first = self._first_item()
        self.current = flagged[0] if flagged and flagged[0] >= first else first
        if not self._has_mission() and self.mode is Mode.MISSION:
            self.body.hold()
            self._set_mode_raw(Mode.HOLD)
        self.statustext(f"Mission: {len(items)} items" if items else "Mission cleared")
        self._emit(M.MAVLINK_MSG_ID_MISSION_CURRENT)

    def _replace_fence(self, items: list[MissionItem]) -> None:
        if items and not self._fence_loaded:
            self._fence_loaded = True
            self._fence_loaded_at = self.clock.sim_time + self.flavour.fence_load_time
        self.fence_items = list(items)
        self.fence = build_fence(self.fence_items, self.frame)
        self.fence_breach = 0
        if items and M.MAVLINK_MSG_ID_FENCE_STATUS not in self.streams:
            self.streams[M.MAVLINK_MSG_ID_FENCE_STATUS] = [1.0, self.clock.stream_time()]
            self.next_due = min(self.next_due, self.clock.stream_time())
        self.statustext(f"Geofence: {len(items)} items" if items else "Geofence cleared")

    def _on_mission_ack(self, msg: Any, addr: Any) -> None:
        if not self._for_me(msg, broadcast_ok=False):
            return
        up = self._upload
        if up is not None and up.partner == (msg.get_srcSystem(), msg.get_srcComponent()):
            log.info("%s: ground station ended the mission upload (result %d)", self.id, msg.type)
            self._upload = None

    def _on_mission_clear_all(self, msg: Any, addr: Any) -> None:
        if not self._for_me(msg, broadcast_ok=False):
            return
        mtype = getattr(msg, "mission_type", 0)
        if mtype in (M.MAV_MISSION_TYPE_MISSION, M.MAV_MISSION_TYPE_ALL):
            self._upload = None
            self._replace_mission([])
        if mtype in (FENCE, M.MAV_MISSION_TYPE_ALL) and self.fence_items:
            self._replace_fence([])
        self._mission_ack((msg.get_srcSystem(), msg.get_srcComponent()), addr, M.MAV_MISSION_ACCEPTED, mtype)

    def _download_items(self) -> list[MissionItem]:
        if not self.flavour.home_is_item0:
            return self.mission
        lat, lon, alt = self.frame.to_geodetic(*self.home)
        home = MissionItem(0, M.MAV_FRAME_GLOBAL, ms.NAV_WAYPOINT, 0, 1, 0, 0, 0, 0,
                           int(round(lat * 1e7)), int(round(lon * 1e7)), alt)
        return [home, *self.mission[1:]]

    def _on_mission_request_list(self, msg: Any, addr: Any) -> None:
        if not self._for_me(msg, broadcast_ok=False):
            return
        mtype = getattr(msg, "mission_type", 0)
        n = len(self._download_items()) if mtype == M.MAV_MISSION_TYPE_MISSION else (
            len(self.fence_items) if mtype == FENCE else 0)
        self._send(self.mav.mission_count_encode(msg.get_srcSystem(), msg.get_srcComponent(), n, mtype), addr)

    def _on_mission_request(self, msg: Any, addr: Any) -> None:
        if not self._for_me(msg, broadcast_ok=False):
            return
        partner = (msg.get_srcSystem(), msg.get_srcComponent())
        mtype = getattr(msg, "mission_type", 0)
        up = self._upload
        if up is not None and up.partner == partner:  # a GCS that uploads does not request
            return
        items = self._download_items() if mtype == M.MAV_MISSION_TYPE_MISSION else (
            self.fence_items if mtype == FENCE else [])
        if not 0 <= msg.seq < len(items):
            self._mission_ack(partner, addr, M.MAV_MISSION_INVALID_SEQUENCE, mtype)
            return
        it = items[msg.seq]
        current = 1 if it.seq == self.current and mtype == M.MAV_MISSION_TYPE_MISSION else 0
        if msg.get_type() == "MISSION_REQUEST_INT":
            out = self.mav.mission_item_int_encode(
                partner[0], partner[1], it.seq, it.frame, it.command, current, it.autocontinue,
                it.param1, it.param2, it.param3, it.param4, it.x, it.y, it.z, mtype)
        else:
            out = self.mav.mission_item_encode(
                partner[0], partner[1], it.seq, it.frame, it.command, current, it.autocontinue,
                it.param1, it.param2, it.param3, it.param4, it.x / 1e7, it.y / 1e7, it.z, mtype)
        self._send(out, addr)

    # ======================================================================================
    # parameters, ping, timesync
    # ======================================================================================
    def _param_value(self, name: str, addr: Any) -> None:
        names = sorted(self.flavour.params)
        self._send(self.mav.param_value_encode(name.encode(), self.flavour.params[name],
                                               M.MAV_PARAM_TYPE_REAL32, len(names), names.index(name)), addr)

    def _on_param_request_list(self, msg: Any, addr: Any) -> None:
        if self._for_me(msg):
            for name in sorted(self.flavour.params):
                self._param_value(name, addr)

    def _on_param_request_read(self, msg: Any, addr: Any) -> None:
        if not self._for_me(msg):
            return
        names = sorted(self.flavour.params)
        name = _param_name(msg.param_id) if msg.param_index < 0 else (
            names[msg.param_index] if msg.param_index < len(names) else "")
        if name in self.flavour.params:
            self._param_value(name, addr)
        else:
            log.debug("%s: unknown parameter %r requested", self.id, name)

    def _on_param_set(self, msg: Any, addr: Any) -> None:
        if not self._for_me(msg):
            return
        name = _param_name(msg.param_id)
        if name not in self.flavour.params:
            log.debug("%s: unknown parameter %r not set", self.id, name)
            return
        if math.isfinite(msg.param_value):
            self.flavour.params[name] = float(msg.param_value)
            self._apply_speed_params()
        self._param_value(name, addr)

    def _apply_speed_params(self) -> None:
        p = self.flavour.params
        speeds = [self.spec.max_speed]
        if self.flavour.px4:
            speeds += [v for v in (p["MPC_XY_CRUISE"], p["MPC_XY_VEL_MAX"]) if v > 0]
        elif p["WPNAV_SPEED"] > 0:
            speeds.append(p["WPNAV_SPEED"] / 100.0)
        self.body.set_speed(min(speeds))

    def _on_ping(self, msg: Any, addr: Any) -> None:
        if msg.target_system == 0:  # a request (a reply would carry our id)
            src = (msg.get_srcSystem(), msg.get_srcComponent())
            self._send(self.mav.ping_encode(msg.time_usec, msg.seq, src[0], src[1]), addr)

    def _on_timesync(self, msg: Any, addr: Any) -> None:
        if msg.tc1 == 0:
            self._send(self.mav.timesync_encode(time.monotonic_ns(), msg.ts1), addr)

    # ======================================================================================
    # telemetry (wall time)
    # ======================================================================================
    def geodetic(self) -> tuple[float, float, float]:
        key = self.body.pos_key()
        if self._geo is None or key != self._geo_key:
            self._geo = self.frame.to_geodetic(*self.body.position)
            self._geo_key = key
        return self._geo

    def geodetic_stale(self) -> bool:
        return self._geo is None or self.body.pos_key() != self._geo_key

    def set_geodetic(self, geo: tuple[float, float, float], key: object) -> None:
        self._geo, self._geo_key = geo, key

    def service(self, now: float, stream_now: float | None = None) -> None:
        """Run the mission upload timer and the link check at wall time ``now`` and send the
        telemetry due at ``stream_now`` (:meth:`Clock.stream_time`; default ``now``)."""
        up = self._upload
        if up is not None and now >= up.deadline:
            up.retries += 1
            if up.retries > ms.MAX_RETRIES:
                self._upload = None
                self.statustext("Mission upload timed out", M.MAV_SEVERITY_WARNING)
                self._mission_ack(up.partner, up.addr, M.MAV_MISSION_OPERATION_CANCELLED, up.mission_type)
            else:
                self._request_item(up)
        if self.gcs_heard is not None:
            self._check_link(now)
        if stream_now is not None:
            now = stream_now
        if now < self.next_due:
            return
        nxt = math.inf
        for msgid, st in self.streams.items():
            if now >= st[1]:
                self._emit(msgid)
                st[1] += st[0]
                if st[1] <= now:
                    st[1] = now + st[0]
            if st[1] < nxt:
                nxt = st[1]
        self.next_due = nxt

    def _emit_heartbeat_now(self) -> None:
        self._emit(M.MAVLINK_MSG_ID_HEARTBEAT)

    def _emit(self, msgid: int) -> None:
        builder = _BUILDERS.get(msgid)
        if builder is not None:
            self._send(builder(self))

    # -- message builders --------------------------------------------------------------------
    def landed_state(self) -> int:
        body = self.body
        if not isinstance(body, Rover) or body.phase is not Phase.AIR:
            return M.MAV_LANDED_STATE_ON_GROUND
        if body.landing or self.mode is Mode.LAND:
            return M.MAV_LANDED_STATE_LANDING
        if self.mode is Mode.TAKEOFF and body.position[2] < 0.5:
            return M.MAV_LANDED_STATE_TAKEOFF
        return M.MAV_LANDED_STATE_IN_AIR

    def battery_fraction(self) -> float:
        frac = self.rover.battery if self.rover is not None else 1.0
        if len(self.faults):
            level = self.faults.battery_level(self.id, self.clock.sim_time)
            if level is not None:
                frac = min(frac, level)
        return frac

    def _time_boot_ms(self) -> int:
        return int(self.clock.sim_time * 1000) & 0xFFFFFFFF

    def _heartbeat(self) -> Any:
        mode = self.mode
        base = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | M.MAV_MODE_FLAG_STABILIZE_ENABLED
        if self.armed:
            base |= M.MAV_MODE_FLAG_SAFETY_ARMED
        if mode in (Mode.MISSION, Mode.RTL, Mode.LAND, Mode.TAKEOFF):
            base |= M.MAV_MODE_FLAG_AUTO_ENABLED | M.MAV_MODE_FLAG_GUIDED_ENABLED
        elif mode in (Mode.GUIDED, Mode.HOLD):
            base |= M.MAV_MODE_FLAG_GUIDED_ENABLED
        if self.battery_fraction() <= 0.0:
            status = M.MAV_STATE_CRITICAL
        else:
            status = M.MAV_STATE_ACTIVE if self.armed else M.MAV_STATE_STANDBY
        return self.mav.heartbeat_encode(self.flavour.mav_type, self.flavour.mav_autopilot, base,
                                         self.flavour.custom_mode(mode), status)

    def _global_position(self) -> Any:
        lat, lon, alt = self.geodetic()
        x, y, z = self.body.position
        vx, vy, vz = self._velocity()
        return self.mav.global_position_int_encode(
            self._time_boot_ms(), int(round(lat * 1e7)), int(round(lon * 1e7)), int(round(alt * 1000)),
            int(round((z - self.home[2]) * 1000)), int(round(vy * 100)), int(round(vx * 100)),
            int(round(-vz * 100)), self._hdg_cdeg())

    def _velocity(self) -> tuple[float, float, float]:
        body = self.body
        return body.velocity if isinstance(body, Rover) else body.vel

    def _hdg_cdeg(self) -> int:
        body = self.body
        heading = body.carrier.heading if isinstance(body, Rover) and body.loaded else body.heading
        return int(round((90.0 - math.degrees(heading)) % 360.0 * 100)) % 36000

    def _cell_mv(self) -> int:
        return int(3500 + 700 * self.battery_fraction())

    def _sys_status(self) -> Any:
        frac = self.battery_fraction()
        health = _SENSORS if frac > 0 else _SENSORS & ~M.MAV_SYS_STATUS_SENSOR_BATTERY
        if len(self.faults) and self.faults.unhealthy(self.id, self.clock.sim_time):
            health &= ~M.MAV_SYS_STATUS_SENSOR_3D_MAG
        return self.mav.sys_status_encode(_SENSORS, _SENSORS, health, 100, 4 * self._cell_mv(), -1,
                                          int(round(frac * 100)), 0, 0, 0, 0, 0, 0)

    def _battery_status(self) -> Any:
        frac = self.battery_fraction()
        if frac <= 0.0:
            state = M.MAV_BATTERY_CHARGE_STATE_EMERGENCY
        elif frac < 0.15:
            state = M.MAV_BATTERY_CHARGE_STATE_CRITICAL
        elif frac < 0.3:
            state = M.MAV_BATTERY_CHARGE_STATE_LOW
        else:
            state = M.MAV_BATTERY_CHARGE_STATE_OK
        cells = [self._cell_mv()] * 4 + [0xFFFF] * 6
        # time_remaining: seconds in the air left at this drain (0 = no estimate), finer than the %
        spec = self.rover.spec if self.rover is not None else None
        left = 0
        if spec is not None and spec.endurance_range:
            left = max(1, int(frac * spec.endurance_range / spec.max_speed)) if frac > 0 else 0
        return self.mav.battery_status_encode(0, M.MAV_BATTERY_FUNCTION_ALL, M.MAV_BATTERY_TYPE_LIPO, 0x7FFF,
                                              cells, -1, -1, -1, int(round(frac * 100)), left, state)

    def _extended_sys_state(self) -> Any:
        return self.mav.extended_sys_state_encode(M.MAV_VTOL_STATE_UNDEFINED, self.landed_state())

    def _home_position(self) -> Any:
        hx, hy, hz = self.home
        if self._home_geo is None or self._home_geo[0] != self.home:
            self._home_geo = (self.home, self.frame.to_geodetic(hx, hy, hz))
        lat, lon, alt = self._home_geo[1]
        return self.mav.home_position_encode(int(round(lat * 1e7)), int(round(lon * 1e7)),
                                             int(round(alt * 1000)), hy, hx, -hz, [1.0, 0.0, 0.0, 0.0],
                                             0.0, 0.0, 0.0, int(self.clock.sim_time * 1e6))

    def _mission_current(self) -> Any:
        n = len(self.mission) - (1 if self.flavour.home_is_item0 and self.mission else 0)
        if not self._has_mission():
            state, total = M.MISSION_STATE_NO_MISSION, 0xFFFF
        else:
            total = n
            if self.finished:
                state = M.MISSION_STATE_COMPLETE
            elif self.mode is Mode.MISSION and self.armed:
                state = M.MISSION_STATE_PAUSED if self.paused else M.MISSION_STATE_ACTIVE
            elif self._item_key is not None and self._item_key[0] == self.mission_version:
                state = M.MISSION_STATE_PAUSED
            else:
                state = M.MISSION_STATE_NOT_STARTED
        mode = 1 if self.mode is Mode.MISSION else 2  # MISSION_MODE_MISSION / MISSION_MODE_SUSPENDED
        return self.mav.mission_current_encode(self.current, total, state, mode)

    def _gps_raw(self) -> Any:
        lat, lon, alt = self.geodetic()
        vx, vy, _ = self._velocity()
        cog = 0xFFFF
        if vx or vy:
            cog = int(round((90.0 - math.degrees(math.atan2(vy, vx))) % 360.0 * 100)) % 36000
        fix, sats = M.GPS_FIX_TYPE_3D_FIX, 14
        if len(self.faults) and self.faults.no_gps(self.id, self.clock.sim_time):
            fix, sats = M.GPS_FIX_TYPE_NO_FIX, 0
        return self.mav.gps_raw_int_encode(int(self.clock.sim_time * 1e6), fix,
                                           int(round(lat * 1e7)), int(round(lon * 1e7)),
                                           int(round(alt * 1000)), 80, 120,
                                           int(round(math.hypot(vx, vy) * 100)), cog, sats)

    def _fence_status(self) -> Any:
        return self.mav.fence_status_encode(1 if self.fence_breach else 0, self.fence_breach_count & 0xFFFF,
                                            self.fence_breach, self._fence_breach_time)

    def _attitude(self) -> Any:
        yaw = math.radians(self._hdg_cdeg() / 100.0)
        if yaw > math.pi:
            yaw -= 2 * math.pi
        return self.mav.attitude_encode(self._time_boot_ms(), 0.0, 0.0, yaw, 0.0, 0.0, 0.0)

    def _vfr_hud(self) -> Any:
        _, _, alt = self.geodetic()
        vx, vy, vz = self._velocity()
        gs = math.hypot(vx, vy)
        return self.mav.vfr_hud_encode(gs, gs, self._hdg_cdeg() // 100, 50 if self.armed else 0, alt, vz)

    def _local_position(self) -> Any:
        x, y, z = self.body.position
        vx, vy, vz = self._velocity()
        return self.mav.local_position_ned_encode(self._time_boot_ms(), y, x, -z, vy, vx, -vz)

    def _system_time(self) -> Any:
        return self.mav.system_time_encode(int(time.time() * 1e6), self._time_boot_ms())

    def _autopilot_version(self) -> Any:
        return self.mav.autopilot_version_encode(
            _CAPABILITIES, self.flavour.sw_version, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0,
            0x51A1_0000_0000 + self.uid)


def _param_name(raw: Any) -> str:
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", "replace")
    return str(raw).split("\x00", 1)[0]


_COMMANDS: dict[int, Callable[[SimVehicle, Command], Any]] = {
    M.MAV_CMD_COMPONENT_ARM_DISARM: SimVehicle._cmd_arm,
    M.MAV_CMD_NAV_TAKEOFF: SimVehicle._cmd_takeoff,
    M.MAV_CMD_NAV_LAND: SimVehicle._cmd_land,
    M.MAV_CMD_NAV_RETURN_TO_LAUNCH: SimVehicle._cmd_rtl,
    M.MAV_CMD_DO_SET_MODE: SimVehicle._cmd_set_mode,
    M.MAV_CMD_MISSION_START: SimVehicle._cmd_mission_start,
    M.MAV_CMD_DO_REPOSITION: SimVehicle._cmd_reposition,
    M.MAV_CMD_DO_SET_MISSION_CURRENT: SimVehicle._cmd_set_current,
    M.MAV_CMD_DO_PAUSE_CONTINUE: SimVehicle._cmd_pause_continue,
    M.MAV_CMD_DO_CHANGE_SPEED: SimVehicle._cmd_change_speed,
    M.MAV_CMD_DO_SET_HOME: SimVehicle._cmd_set_home,
    M.MAV_CMD_REQUEST_MESSAGE: SimVehicle._cmd_request_message,
    M.MAV_CMD_BATTERY_RESET: SimVehicle._cmd_battery_reset,
    M.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: SimVehicle._cmd_request_capabilities,
    M.MAV_CMD_SET_MESSAGE_INTERVAL: SimVehicle._cmd_set_interval,
    M.MAV_CMD_GET_MESSAGE_INTERVAL: SimVehicle._cmd_get_interval,
}

_BUILDERS: dict[int, Callable[[SimVehicle], Any]] = {
    M.MAVLINK_MSG_ID_HEARTBEAT: SimVehicle._heartbeat,
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: SimVehicle._global_position,
    M.MAVLINK_MSG_ID_SYS_STATUS: SimVehicle._sys_status,
    M.MAVLINK_MSG_ID_BATTERY_STATUS: SimVehicle._battery_status,
    M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: SimVehicle._extended_sys_state,
    M.MAVLINK_MSG_ID_HOME_POSITION: SimVehicle._home_position,
    M.MAVLINK_MSG_ID_MISSION_CURRENT: SimVehicle._mission_current,
    M.MAVLINK_MSG_ID_GPS_RAW_INT: SimVehicle._gps_raw,
    M.MAVLINK_MSG_ID_ATTITUDE: SimVehicle._attitude,
    M.MAVLINK_MSG_ID_VFR_HUD: SimVehicle._vfr_hud,
    M.MAVLINK_MSG_ID_LOCAL_POSITION_NED: SimVehicle._local_position,
    M.MAVLINK_MSG_ID_SYSTEM_TIME: SimVehicle._system_time,
    M.MAVLINK_MSG_ID_AUTOPILOT_VERSION: SimVehicle._autopilot_version,
    M.MAVLINK_MSG_ID_FENCE_STATUS: SimVehicle._fence_status,
}

__all__ = ["SimVehicle", "Command", "Clock", "Link"]
