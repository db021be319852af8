"""What a vehicle's health telemetry means, in words (the MAVLink side of the preflight checks in
:mod:`fleetctl.run.preflight`): its system state (HEARTBEAT ``system_status``), its GPS fix
(GPS_RAW_INT), its sensors (SYS_STATUS), ArduPilot's "PreArm:" text, and asking once for what has
not come yet (:func:`request_missing`)."""

from __future__ import annotations

import time

from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.mavlink.link import enum_name
from fleetctl.mavlink.vehicle import Vehicle

NOT_REQUIRED = M.MAV_SYS_STATUS_SENSOR_RC_RECEIVER  # an RC receiver's health does not stop a mission
PREARM_TEXT_AGE = 60.0  # s: a "PreArm:" STATUSTEXT older than this no longer explains a failing check
STATE_FAILING = (M.MAV_STATE_EMERGENCY, M.MAV_STATE_POWEROFF, M.MAV_STATE_FLIGHT_TERMINATION)
STATE_CRITICAL = M.MAV_STATE_CRITICAL  # a failsafe is active (a warning)
_SENSOR_WORDS = {
    "3D_GYRO": "gyroscope", "3D_ACCEL": "accelerometer", "3D_MAG": "magnetometer",
    "ABSOLUTE_PRESSURE": "barometer", "GPS": "GPS", "AHRS": "attitude estimator",
    "MOTOR_OUTPUTS": "motor outputs", "BATTERY": "battery", "RC_RECEIVER": "RC receiver",
}
_STATE = {0: "uninitialised", 1: "booting", 2: "calibrating", 3: "standby", 4: "active", 5: "critical",
          6: "emergency", 7: "power-off", 8: "flight termination"}
_FIX = {0: "no GPS", 1: "no fix", 2: "2D fix", 3: "3D fix", 4: "DGPS", 5: "RTK float", 6: "RTK fixed",
        7: "static", 8: "PPP"}


def state_words(status: int) -> str:
    """``system_status`` (MAV_STATE) in words."""
    return _STATE.get(status, f"state {status}")


def fix_words(fix: int) -> str:
    """A GPS_FIX_TYPE in words."""
    return _FIX.get(fix, f"fix type {fix}")


def has_3d_fix(fix: int) -> bool:
    return fix >= M.GPS_FIX_TYPE_3D_FIX


def unhealthy_sensors(v: Vehicle) -> list[str]:
    """Names of the sensors SYS_STATUS reports present (and enabled) but not healthy."""
    if v.sensors_present is None or v.sensors_health is None:
        return []
    bad = v.sensors_present & ~v.sensors_health & ~NOT_REQUIRED
    if v.sensors_enabled:
        bad &= v.sensors_enabled
    out = []
    bit = 1
    while bit <= bad:
        if bad & bit:
            name = enum_name("MAV_SYS_STATUS_SENSOR", bit).removeprefix("MAV_SYS_STATUS_SENSOR_")
            name = name.removeprefix("MAV_SYS_STATUS_")
            out.append(_SENSOR_WORDS.get(name, name.lower().replace("_", " ")))
        bit <<= 1
    return out


def prearm_text(v: Vehicle, within: float = PREARM_TEXT_AGE) -> str | None:
    """The vehicle's last "PreArm: …" STATUSTEXT (ArduPilot says there why it cannot arm yet)."""
    now = time.monotonic()
    return next((text for ts, _sev, text in reversed(v.statustexts)
                 if text.startswith("PreArm") and now - ts <= within), None)


async def request_missing(v: Vehicle, timeout: float = 0.5) -> None:
    """Ask once (REQUEST_MESSAGE) for the health messages ``v`` has not sent yet: HOME_POSITION,
    GPS_RAW_INT, SYS_STATUS. Errors (a refused or unanswered request) go to the caller."""
    for msgid, have in ((M.MAVLINK_MSG_ID_HOME_POSITION, v.home),
                        (M.MAVLINK_MSG_ID_GPS_RAW_INT, v.gps_fix_type),
                        (M.MAVLINK_MSG_ID_SYS_STATUS, v.sensors_present)):
        if have is None:
            await v.request_message(msgid, timeout=timeout)


__all__ = ["NOT_REQUIRED", "PREARM_TEXT_AGE", "STATE_CRITICAL", "STATE_FAILING", "fix_words", "has_3d_fix",
           "prearm_text", "request_missing", "state_words", "unhealthy_sensors"]
