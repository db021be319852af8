"""Mission items as a vehicle stores them, their validation and the upload transfer state."""

from __future__ import annotations

import math
import zlib
from dataclasses import astuple, dataclass, field

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from .geo import LocalFrame

NAV_WAYPOINT = mavlink2.MAV_CMD_NAV_WAYPOINT
NAV_LOITER_UNLIM = mavlink2.MAV_CMD_NAV_LOITER_UNLIM
NAV_LOITER_TIME = mavlink2.MAV_CMD_NAV_LOITER_TIME
NAV_RTL = mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH
NAV_LAND = mavlink2.MAV_CMD_NAV_LAND
NAV_TAKEOFF = mavlink2.MAV_CMD_NAV_TAKEOFF
DO_CHANGE_SPEED = mavlink2.MAV_CMD_DO_CHANGE_SPEED
NAV_DELAY = mavlink2.MAV_CMD_NAV_DELAY  # param1: s to wait where the vehicle is (in the air or landed)

POSITIONAL = {NAV_WAYPOINT, NAV_LOITER_UNLIM, NAV_LOITER_TIME, NAV_LAND, NAV_TAKEOFF}
SUPPORTED = POSITIONAL | {NAV_RTL, DO_CHANGE_SPEED, NAV_DELAY}

FRAME_GLOBAL = {mavlink2.MAV_FRAME_GLOBAL, mavlink2.MAV_FRAME_GLOBAL_INT}
FRAME_RELATIVE = {
    mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT, mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT, mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,  # flat terrain
}
FRAMES_WITH_POSITION = FRAME_GLOBAL | FRAME_RELATIVE
FRAME_MISSION = mavlink2.MAV_FRAME_MISSION

MAX_ITEMS = 2000
ITEM_TIMEOUT = 1.5  # s (wall) before the vehicle re-requests an item (MAVLink spec default)
MAX_RETRIES = 5


@dataclass
class MissionItem:
    """A mission item in MISSION_ITEM_INT form (x, y = degrees * 1e7 for global frames)."""

    seq: int
    frame: int
    command: int
    current: int
    autocontinue: int
    param1: float
    param2: float
    param3: float
    param4: float
    x: int
    y: int
    z: float
    mission_type: int = 0

    @classmethod
    def from_msg(cls, msg: mavlink2.MAVLink_message) -> MissionItem:
        """From MISSION_ITEM_INT, or the legacy float MISSION_ITEM (x, y in degrees)."""
        x, y = msg.x, msg.y
        if msg.get_type() == "MISSION_ITEM":
            x = int(round(x * 1e7)) if math.isfinite(x) else 0
            y = int(round(y * 1e7)) if math.isfinite(y) else 0
        return cls(
            seq=msg.seq, frame=msg.frame, command=msg.command, current=msg.current,
            autocontinue=msg.autocontinue, param1=msg.param1, param2=msg.param2,
            param3=msg.param3, param4=msg.param4, x=int(x), y=int(y), z=msg.z,
            mission_type=getattr(msg, "mission_type", 0),
        )

    @property
    def lat(self) -> float:
        return self.x / 1e7

    @property
    def lon(self) -> float:
        return self.y / 1e7

    def has_latlon(self) -> bool:
        return self.frame in FRAMES_WITH_POSITION and not (self.x == 0 and self.y == 0)


def validate(item: MissionItem, home_item: bool) -> int:
    """MAV_MISSION_RESULT for one uploaded item (MAV_MISSION_ACCEPTED if it can be flown)."""
    if home_item:
        return mavlink2.MAV_MISSION_ACCEPTED
    if item.command not in SUPPORTED:
        return mavlink2.MAV_MISSION_UNSUPPORTED
    if item.command in POSITIONAL and item.frame not in FRAMES_WITH_POSITION:
        return mavlink2.MAV_MISSION_UNSUPPORTED_FRAME
    if item.command in POSITIONAL:
        if not -90.0 <= item.lat <= 90.0:
            return mavlink2.MAV_MISSION_INVALID_PARAM5_X
        if not -180.0 <= item.lon <= 180.0:
            return mavlink2.MAV_MISSION_INVALID_PARAM6_Y
        if not (math.isfinite(item.z) or item.command in (NAV_TAKEOFF, NAV_LAND)):
            return mavlink2.MAV_MISSION_INVALID_PARAM7
    return mavlink2.MAV_MISSION_ACCEPTED


def item_target(
    item: MissionItem, frame: LocalFrame, home_z: float, here: tuple[float, float, float]
) -> tuple[float, float, float]:
    """ENU target of a positional item; lat = lon = 0 means here, a NaN altitude keeps the height."""
    if item.has_latlon():
        x, y, _ = frame.to_enu(item.lat, item.lon, frame.alt0)
    else:
        x, y = here[0], here[1]
    if not math.isfinite(item.z):
        z = here[2]
    elif item.frame in FRAME_GLOBAL:
        z = item.z - frame.alt0
    else:
        z = home_z + item.z
    return x, y, max(z, 0.0)


def mission_id(items: list[MissionItem]) -> int:
    """A 32-bit id of a mission's content (like PX4's CRC), 0 for no mission."""
    if not items:
        return 0
    return zlib.crc32(repr([astuple(i) for i in items]).encode()) or 1


@dataclass
class Upload:
    """A mission upload in progress (vehicle side)."""

    partner: tuple[int, int]
    addr: object
    count: int
    mission_type: int
    items: list[MissionItem] = field(default_factory=list)
    deadline: float = 0.0
    retries: int = 0
    int_mode: bool = True

    @property
    def expected(self) -> int:
        return len(self.items)
