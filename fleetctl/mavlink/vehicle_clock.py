"""A mission clock that follows the vehicles' own time (``time_boot_ms``): for lockstep SITL firmware.

Lockstep SITL firmware (ArduPilot ``-S --speedup X``, PX4 ``PX4_SIM_SPEED_FACTOR``, ArduPilot on
``sitl.json_physics``) runs at the pace of its physics, and on a busy machine that is slower than the
speed-up it was asked for (ArduPilot on the Python ``sitl.json_physics`` at 2.2 - 3.4x instead of 4x).
The wall clock times ``--speedup`` then counts more mission seconds than the vehicles flew, and a
flight looks longer than its plan. :class:`VehicleTimeClock` counts the vehicles' seconds instead:

* every ``time_boot_ms`` a vehicle sends (:meth:`observe`, fed from its GLOBAL_POSITION_INT) gives
  the clock a reading: the vehicle's boot time plus that vehicle's offset, set when it is first
  heard so that its time lines up with the clock as it stands; the clock takes the most advanced
  reading of any vehicle (one that stopped or lags does not hold it back);
* between readings it runs on at ``rate`` times the wall clock, and it never goes back: it is at most
  one reading interval times ``rate`` ahead of the vehicles (0.4 mission s at 10 Hz and 4x);
* without readings (before the first, or when every vehicle is silent) it is the wall clock times
  ``rate``, so every wait on it still ends; a vehicle heard again after ``SILENCE_GAP`` wall seconds
  is lined up anew with the clock as it stands (which goes on from there at the vehicle's pace);
* a vehicle whose time goes back (it rebooted) or jumps further than ``rate`` times the wall time
  since its last reading allows (``STEP_FACTOR``, ``STEP_SLACK``) is lined up anew, never followed.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

STEP_FACTOR = 2.0  # a vehicle's time may advance at most this many times `rate` times the wall time ...
STEP_SLACK = 1.0  # ... plus this many seconds between two of its readings; further is a jump, not followed
SILENCE_GAP = 1.0  # wall s without a reading of a vehicle after which it is lined up anew


@dataclass
class _Source:
    boot: float  # s: its last time_boot_ms
    wall: float  # wall s it came at
    offset: float  # mission s = boot + offset


class VehicleTimeClock:
    """Mission seconds following the vehicles' ``time_boot_ms`` (see the module docstring); call it
    for the time, :meth:`observe` with each vehicle's boot time."""

    def __init__(self, rate: float, wall: Callable[[], float] = time.monotonic) -> None:
        if not rate > 0:
            raise ValueError(f"rate must be > 0, got {rate}")
        self.rate = float(rate)
        self._wall = wall
        now = wall()
        self._mission, self._at = now * self.rate, now  # the last reading: mission s at wall s
        self._shown = self._mission  # the latest time told: the clock never goes back
        self._sources: dict[int, _Source] = {}
        self.readings = 0  # vehicle readings the clock followed

    def __call__(self) -> float:
        t = self._mission + (self._wall() - self._at) * self.rate
        if t > self._shown:
            self._shown = t
        return self._shown

    def observe(self, source: int, time_boot_ms: int) -> None:
        """A vehicle (``source``: its system id) says its clock reads ``time_boot_ms``."""
        boot, wall = time_boot_ms / 1000.0, self._wall()
        src = self._sources.get(source)
        if (src is None or boot < src.boot or wall - src.wall > SILENCE_GAP
                or boot - src.boot > self._max_step(wall - src.wall)):
            self._sources[source] = _Source(boot, wall, self() - boot)  # first, silent, rebooted, jumped
            return
        if boot == src.boot:
            return
        src.boot, src.wall = boot, wall
        reading = boot + src.offset
        if reading > self._mission:
            self._mission, self._at = reading, wall
            self.readings += 1

    def _max_step(self, wall_gap: float) -> float:
        return max(wall_gap, 0.0) * self.rate * STEP_FACTOR + STEP_SLACK


__all__ = ["SILENCE_GAP", "STEP_FACTOR", "STEP_SLACK", "VehicleTimeClock"]
