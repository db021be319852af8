"""A geofence as a simulated autopilot stores it (mission_type FENCE) and checks it.

Items: MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION / _EXCLUSION (param1 = the polygon's vertex
count, consecutive items form one polygon) and MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION / _EXCLUSION
(param1 = radius in metres). A position breaches the fence when it is outside any inclusion zone
or inside any exclusion zone; the altitude limit comes from the flavour's parameters.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from .geo import LocalFrame
from .mission import MissionItem

M = mavlink2
POLY_IN = M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
POLY_OUT = M.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
CIRCLE_IN = M.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION
CIRCLE_OUT = M.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
FENCE_COMMANDS = {POLY_IN, POLY_OUT, CIRCLE_IN, CIRCLE_OUT}

Pt = tuple[float, float]


def inside(poly: list[Pt], x: float, y: float) -> bool:
    """Ray casting: is (x, y) inside the polygon (boundary counts as inside, within 1 mm)?"""
    n = len(poly)
    hit = False
    for i in range(n):
        (x1, y1), (x2, y2) = poly[i], poly[(i + 1) % n]
        if _on_segment(x, y, x1, y1, x2, y2):
            return True
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            hit = not hit
    return hit


def _on_segment(x: float, y: float, x1: float, y1: float, x2: float, y2: float) -> bool:
    dx, dy = x2 - x1, y2 - y1
    L2 = dx * dx + dy * dy
    t = 0.0 if L2 == 0 else max(0.0, min(1.0, ((x - x1) * dx + (y - y1) * dy) / L2))
    return math.hypot(x - (x1 + t * dx), y - (y1 + t * dy)) < 1e-3


@dataclass
class Fence:
    """The zones of an uploaded fence in the local ENU frame."""

    inclusions: list[list[Pt]] = field(default_factory=list)
    exclusions: list[list[Pt]] = field(default_factory=list)
    circles_in: list[tuple[Pt, float]] = field(default_factory=list)
    circles_out: list[tuple[Pt, float]] = field(default_factory=list)

    @property
    def has_zones(self) -> bool:
        return bool(self.inclusions or self.exclusions or self.circles_in or self.circles_out)

    def outside(self, x: float, y: float) -> bool:
        """True when (x, y) breaches the horizontal fence."""
        if any(not inside(p, x, y) for p in self.inclusions):
            return True
        if any(math.hypot(x - c[0], y - c[1]) > r for c, r in self.circles_in):
            return True
        if any(inside(p, x, y) for p in self.exclusions):
            return True
        return any(math.hypot(x - c[0], y - c[1]) < r for c, r in self.circles_out)


def validate_fence(items: list[MissionItem]) -> int:
    """MAV_MISSION_RESULT of a whole fence upload (polygons complete, vertex counts consistent)."""
    i = 0
    while i < len(items):
        it = items[i]
        if it.command not in FENCE_COMMANDS:
            return M.MAV_MISSION_UNSUPPORTED
        if not it.has_latlon():
            return M.MAV_MISSION_INVALID_PARAM5_X
        if it.command in (CIRCLE_IN, CIRCLE_OUT):
            if not it.param1 > 0:
                return M.MAV_MISSION_INVALID_PARAM1
            i += 1
            continue
        n = int(it.param1)
        if n < 3 or i + n > len(items):
            return M.MAV_MISSION_INVALID_PARAM1
        if any(items[j].command != it.command or int(items[j].param1) != n for j in range(i, i + n)):
            return M.MAV_MISSION_INVALID_PARAM1
        i += n
    return M.MAV_MISSION_ACCEPTED


def build_fence(items: list[MissionItem], frame: LocalFrame) -> Fence:
    """The zones of a validated fence upload."""
    fence = Fence()
    i = 0
    while i < len(items):
        it = items[i]
        x, y, _ = frame.to_enu(it.lat, it.lon, frame.alt0)
        if it.command in (CIRCLE_IN, CIRCLE_OUT):
            (fence.circles_in if it.command == CIRCLE_IN else fence.circles_out).append(((x, y), it.param1))
            i += 1
            continue
        n = int(it.param1)
        poly = [frame.to_enu(items[j].lat, items[j].lon, frame.alt0)[:2] for j in range(i, i + n)]
        (fence.inclusions if it.command == POLY_IN else fence.exclusions).append(poly)
        i += n
    return fence


__all__ = ["FENCE_COMMANDS", "Fence", "build_fence", "inside", "validate_fence"]
