"""A mission clock that follows the vehicles' own time (``time_boot_ms``): for lockstep SITL firmware.

Lockstep SITL firmware (ArduPilot ``-S --speedup X``, PX4 ``PX4_SIM_SPEED_FACTOR``, ArduPilot on
``sitl.json_physics``) runs at the pace of its physics, and on a busy machine that is slower than the
speed-up it was asked for (ArduPilot on the Python ``sitl.json_physics`` at 2.2 - 3.4x instead of 4x).
The wall clock times ``--speedup`` then counts more mission seconds than the vehicles flew, and a
flight looks longer than its plan. :class:`VehicleTimeClock` counts the vehicles' seconds instead:

* the clock follows one vehicle, its *leader*: the ``reference`` (the carrier, set by the run)
  while it is heard, else the vehicle it followed last, else the first heard. Each SITL instance
  keeps its own lockstep clock, and following the most advanced of several jittering clocks would
  run ahead of every one of them;
* every ``time_boot_ms`` the leader sends (:meth:`observe`, fed from its GLOBAL_POSITION_INT) is a
  reading: its boot time plus its offset, set when it became the leader so that its time lines up
  with the clock as it stands (no jump); a leader whose time has not advanced for ``SILENCE_GAP``
  wall seconds (silent, lost, hung) hands over to the next vehicle heard;
* between readings it runs on at ``rate`` times the wall clock, and it never goes back: it is at most
  one reading interval times ``rate`` ahead of the vehicles (0.4 mission s at 10 Hz and 4x);
* without readings (before the first, or when every vehicle is silent) it is the wall clock times
  ``rate``, so every wait on it still ends;
* a leader whose time goes back (it rebooted) or jumps further than ``rate`` times the wall time
  since its last reading allows (``STEP_FACTOR``, ``STEP_SLACK``) is lined up anew, never followed.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Hashable

STEP_FACTOR = 2.0  # a vehicle's time may advance at most this many times `rate` times the wall time ...
STEP_SLACK = 1.0  # ... plus this many seconds between two of its readings; further is a jump, not followed
SILENCE_GAP = 1.0  # wall s without its time advancing after which the leader hands over


class VehicleTimeClock:
    """Mission seconds following the vehicles' ``time_boot_ms`` (see the module docstring); call it
    for the time, :meth:`observe` with each vehicle's boot time; ``reference``: the vehicle to
    follow while it is heard (the carrier; a vehicle is named by its id, which unlike its system id
    is unique across links)."""

    def __init__(self, rate: float, wall: Callable[[], float] = time.monotonic) -> None:
        if not rate > 0:
            raise ValueError(f"rate must be > 0, got {rate}")
        self.rate = float(rate)
        self.reference: Hashable | None = None
        self._wall = wall
        now = wall()
        self._mission, self._at = now * self.rate, now  # the last reading: mission s at wall s
        self._shown = self._mission  # the latest time told: the clock never goes back
        self._leader: Hashable | None = None
        self._boot = 0.0  # the leader's last time_boot_ms, s
        self._heard = -float("inf")  # wall s its time last advanced
        self._offset = 0.0  # mission s = its boot s + offset
        self._reference_boot: float | None = None  # the reference's last time_boot_ms, s
        self.readings = 0  # readings the clock followed
        self.leaders: list[Hashable] = []  # the vehicles it followed, in order

    def __call__(self) -> float:
        t = self._mission + (self._wall() - self._at) * self.rate
        if t > self._shown:
            self._shown = t
        return self._shown

    def observe(self, source: Hashable, time_boot_ms: int) -> None:
        """A vehicle (``source``: its id) says its clock reads ``time_boot_ms``."""
        boot, wall = time_boot_ms / 1000.0, self._wall()
        reference = source == self.reference and boot != self._reference_boot  # its time goes on
        if source == self.reference:
            self._reference_boot = boot
        if source != self._leader:
            silent = wall - self._heard > SILENCE_GAP
            if self._leader is None or silent or reference:
                self._lead(source, boot, wall)
            return
        if boot == self._boot:
            return
        gap = wall - self._heard
        if boot < self._boot or gap > SILENCE_GAP or boot - self._boot > self._max_step(gap):
            self._lead(source, boot, wall)  # it rebooted, was silent or its time jumped: lined up anew
            return
        self._boot, self._heard = boot, wall
        reading = boot + self._offset
        if reading > self._mission:
            self._mission, self._at = reading, wall
            self.readings += 1

    def _lead(self, source: Hashable, boot: float, wall: float) -> None:
        """Follow ``source`` from now on, its time lined up with the clock as it stands."""
        if source != self._leader:
            self.leaders.append(source)
        self._offset = self() - boot
        self._leader, self._boot, self._heard = source, boot, wall

    def _max_step(self, wall_gap: float) -> float:
        return max(wall_gap, 0.0) * self.rate * STEP_FACTOR + STEP_SLACK


__all__ = ["SILENCE_GAP", "STEP_FACTOR", "STEP_SLACK", "VehicleTimeClock"]
