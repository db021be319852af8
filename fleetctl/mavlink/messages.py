"""MAVLink values as fleetctl handles them: enum names (:func:`enum_name`), a mission item in
MISSION_ITEM_INT form (:class:`MissionItem`), a command's final acknowledgement
(:class:`CommandAck`) and the degrees·1e7 encoding of COMMAND_INT (:func:`deg_e7`). pymavlink is the
codec (``pymavlink.dialects.v20.ardupilotmega``)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as M


def enum_name(enum: str, value: int) -> str:
    """The MAVLink name of ``value`` in ``enum`` (e.g. ``MAV_RESULT_DENIED``), or ``ENUM(value)``."""
    entry = M.enums.get(enum, {}).get(value)
    return entry.name if entry is not None else f"{enum}({value})"


def command_name(command: int) -> str:
    return enum_name("MAV_CMD", command)


@dataclass(frozen=True)
class MissionItem:
    """One mission item in MISSION_ITEM_INT form: ``x``/``y`` are degrees·1e7 in global frames,
    ``z`` metres (relative to home in ``MAV_FRAME_GLOBAL_RELATIVE_ALT_INT``)."""

    command: int
    frame: int = M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: int = 0
    y: int = 0
    z: float = 0.0
    autocontinue: int = 1
    current: int = 0

    @property
    def lat(self) -> float:
        return self.x / 1e7

    @property
    def lon(self) -> float:
        return self.y / 1e7

    @property
    def name(self) -> str:
        return command_name(self.command).removeprefix("MAV_CMD_")

    @classmethod
    def from_msg(cls, msg: Any) -> MissionItem:
        """From a MISSION_ITEM_INT (or legacy float MISSION_ITEM) message."""
        x, y = msg.x, msg.y
        if msg.get_type() == "MISSION_ITEM":
            x = int(round(x * 1e7)) if math.isfinite(x) else 0
            y = int(round(y * 1e7)) if math.isfinite(y) else 0
        return cls(command=msg.command, frame=msg.frame, param1=msg.param1, param2=msg.param2,
                   param3=msg.param3, param4=msg.param4, x=int(x), y=int(y), z=msg.z,
                   autocontinue=msg.autocontinue, current=msg.current)

    def same_as(self, other: MissionItem, tol: float = 1e-3) -> bool:
        """Equal up to float32 rounding of the parameters and ``z`` (what survives a round trip)."""
        def close(a: float, b: float) -> bool:
            return (math.isnan(a) and math.isnan(b)) or math.isclose(a, b, rel_tol=1e-6, abs_tol=tol)

        return (self.command == other.command and self.frame == other.frame and self.x == other.x
                and self.y == other.y and self.autocontinue == other.autocontinue
                and all(close(a, b) for a, b in zip(
                    (self.param1, self.param2, self.param3, self.param4, self.z),
                    (other.param1, other.param2, other.param3, other.param4, other.z), strict=True)))


@dataclass(frozen=True)
class CommandAck:
    """The final COMMAND_ACK of a command (after retries), or - ``by_effect`` - no ACK at all but
    the vehicle's telemetry showing the command done (:mod:`fleetctl.mavlink.effects`; then
    ``result`` is MAV_RESULT_ACCEPTED and ``attempts`` 0)."""

    sysid: int
    command: int
    result: int
    attempts: int
    progress: int = 0
    result_param2: int = 0
    by_effect: bool = False

    @property
    def accepted(self) -> bool:
        return self.result == M.MAV_RESULT_ACCEPTED

    @property
    def result_name(self) -> str:
        return enum_name("MAV_RESULT", self.result)

    @property
    def command_name(self) -> str:
        return command_name(self.command)


def deg_e7(deg: float) -> int:
    """Degrees → degrees·1e7 for COMMAND_INT; NaN means 'not given' (INT32_MAX)."""
    if not math.isfinite(deg):
        return 0x7FFFFFFF
    return int(round(deg * 1e7))


__all__ = ["CommandAck", "MissionItem", "command_name", "deg_e7", "enum_name"]
