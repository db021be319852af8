"""ArduPilot's JSON SITL wire format (``libraries/SITL/examples/JSON/readme.md``).

The firmware sends binary servo packets: ``uint16 magic, uint16 frame_rate, uint32 frame_count,
uint16 pwm[16]`` (magic 18458) or ``pwm[32]`` (magic 29569, ``SERVO_32_ENABLE``), little-endian.
The physics answers each with one line of JSON. The firmware's reader is not a JSON parser: it
finds each key with ``strstr``, skips the key, its closing quote and one character (the colon)
and reads ``[%f, %f, %f]`` -- so there must be no space after a colon (compact separators), and
numbers must be finite.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

from .body import Body

MAGIC_16 = 18458
MAGIC_32 = 29569
_HEADER = struct.Struct("<HHI")
_PWM = {MAGIC_16: struct.Struct("<16H"), MAGIC_32: struct.Struct("<32H")}


@dataclass(frozen=True)
class ServoPacket:
    frame_rate: int
    frame_count: int
    pwm: tuple[int, ...]


def parse_servo(data: bytes) -> ServoPacket | None:
    """A servo packet, or None for anything else (wrong magic or length)."""
    if len(data) < _HEADER.size:
        return None
    magic, rate, count = _HEADER.unpack_from(data)
    pwm = _PWM.get(magic)
    if pwm is None or len(data) != _HEADER.size + pwm.size:
        return None
    return ServoPacket(rate, count, pwm.unpack_from(data, _HEADER.size))


def encode_servo(frame_rate: int, frame_count: int, pwm: tuple[int, ...]) -> bytes:
    """A servo packet as the firmware sends it (for tests and stubs)."""
    magic = MAGIC_32 if len(pwm) > 16 else MAGIC_16
    channels = tuple(pwm) + (0,) * ((32 if magic == MAGIC_32 else 16) - len(pwm))
    return _HEADER.pack(magic, frame_rate, frame_count) + _PWM[magic].pack(*channels)


def _f(x: float) -> str:
    return repr(float(x)) if math.isfinite(x) else "0.0"


def _vec(v: tuple[float, ...]) -> str:
    return "[" + ",".join(_f(x) for x in v) + "]"


def encode_state(timestamp: float, body: Body, origin: tuple[float, float, float]) -> bytes:
    """The state line for ``body`` with its position taken relative to ``origin`` (the
    vehicle's home), framed by newlines as the readme asks."""
    p = body.position
    rel = (p[0] - origin[0], p[1] - origin[1], p[2] - origin[2])
    return ("\n{\"timestamp\":" + _f(timestamp)
            + ",\"imu\":{\"gyro\":" + _vec(body.gyro) + ",\"accel_body\":" + _vec(body.accel_body) + "}"
            + ",\"position\":" + _vec(rel)
            + ",\"quaternion\":" + _vec(body.attitude)
            + ",\"velocity\":" + _vec(body.velocity) + "}\n").encode()
