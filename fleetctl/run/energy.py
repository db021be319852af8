"""Battery → flight range (docs/mavlink.md, "Telemetry read").

``range = (remaining - reserve) · endurance_range``, clamped at 0: the reserve fraction of the
battery is never planned away, and ``endurance_range`` is the distance a rover flies on a full
battery (mission file ``rovers.endurance_range``).
"""

from __future__ import annotations

import math


def battery_range(remaining: float, reserve: float, endurance_range: float) -> float:
    """Metres a rover may still plan to fly.

    ``remaining`` and ``reserve`` are fractions of a full battery (0..1; a percentage from
    telemetry is ``pct / 100``); ``endurance_range`` is metres on a full battery.
    """
    for name, val in (("remaining", remaining), ("reserve", reserve), ("endurance_range", endurance_range)):
        if not math.isfinite(val):
            raise ValueError(f"{name} must be a finite number, got {val!r}")
    if not 0.0 <= reserve <= 1.0:
        raise ValueError(f"reserve is a fraction of the battery in 0..1, got {reserve}")
    if endurance_range < 0:
        raise ValueError(f"endurance_range must be >= 0 m, got {endurance_range}")
    remaining = min(max(remaining, 0.0), 1.0)
    return max(0.0, (remaining - reserve) * endurance_range)


def range_from_percent(percent: float | None, reserve: float, endurance_range: float) -> float | None:
    """:func:`battery_range` from a telemetry percentage (None when the vehicle reports none)."""
    if percent is None:
        return None
    return battery_range(percent / 100.0, reserve, endurance_range)


__all__ = ["battery_range", "range_from_percent"]
