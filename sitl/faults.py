"""Fault injection: the faults a mission file's ``sim.faults`` list or a test can switch on.

A fault is active for a vehicle (or every vehicle when ``vehicle`` is None) from simulated time
``at`` until simulated time ``until`` (None = never back). ``latency`` is the one-way delay of every
datagram in each direction, in wall seconds (it is a property of the link, like the MAVLink
timeouts it interacts with).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any

KINDS = ("dropout", "packet_loss", "latency", "battery_drain", "refuse_arm", "reject_mission",
         "no_gps", "unhealthy", "low_battery", "drive_off", "land_drift")
_KIND_KEYS: dict[str, set[str]] = {
    "dropout": set(),
    "packet_loss": {"rate"},
    "latency": {"seconds"},
    "battery_drain": {"factor"},
    "refuse_arm": set(),
    "reject_mission": set(),
    "no_gps": set(),
    "unhealthy": set(),
    "low_battery": {"level"},
    "drive_off": set(),
    "land_drift": {"distance"},
}
_COMMON_KEYS = {"kind", "vehicle", "at", "until"}


class FaultError(ValueError):
    """A fault description that cannot be used; the message says what to change."""


@dataclass(frozen=True)
class Fault:
    """One fault. ``rate`` is for packet_loss (0..1), ``seconds`` for latency, ``factor`` for
    battery_drain (2.0 = battery empties after half the endurance range). ``reject_mission``: the
    vehicle answers every mission upload (MISSION_COUNT) with a STATUSTEXT giving its reason and a
    MAV_MISSION_DENIED MISSION_ACK, like an autopilot whose feasibility check fails.

    Preflight faults: ``no_gps`` - GPS_RAW_INT reports fix_type 1 (no fix) and 0 satellites;
    GLOBAL_POSITION_INT keeps streaming (the simulated estimator still knows where it is, so only
    the GPS check fails) and arming is denied. ``unhealthy`` - the magnetometer is present but not
    healthy in SYS_STATUS (arming denied). ``low_battery`` - the battery reads at most ``level``
    (0..1) while the fault is active (a rover's battery is drained down to it).

    ``drive_off`` (a carrier): while active it drives on along its heading at its cruise speed,
    whatever its mission or commands say (as PX4's SIH Ackermann carrier once drove 57 m on from a
    stop it had reported reached); when the fault ends it stops where it is and stays there until
    its mission is moved on (a current item set again).

    ``land_drift`` (a rover): a landing begun while it is active drifts ``distance`` metres east on
    the way down, in step with the descent (PX4 1.18 SIH's LAND mode moved quadcopters 0.1 - 1.1 m
    sideways on a descent from 3 m): a rover sent down over the deck may touch down beside it."""

    kind: str
    vehicle: str | None = None
    at: float = 0.0
    until: float | None = None
    rate: float = 0.0
    seconds: float = 0.0
    factor: float = 1.0
    level: float = 1.0  # low_battery
    distance: float = 0.0  # land_drift: metres east over a landing's descent

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise FaultError(f"unknown fault kind {self.kind!r}; use one of {', '.join(KINDS)}")
        if not math.isfinite(self.at) or self.at < 0:
            raise FaultError(f"fault {self.kind}: 'at' must be a time >= 0 s, got {self.at}")
        if self.until is not None and not self.until > self.at:
            raise FaultError(f"fault {self.kind}: 'until' ({self.until}) must be later than 'at' ({self.at})")
        if not 0.0 <= self.rate <= 1.0:
            raise FaultError(f"fault packet_loss: 'rate' must be within 0..1, got {self.rate}")
        if not (math.isfinite(self.seconds) and self.seconds >= 0):
            raise FaultError(f"fault latency: 'seconds' must be >= 0, got {self.seconds}")
        if not (math.isfinite(self.factor) and self.factor >= 0):
            raise FaultError(f"fault battery_drain: 'factor' must be >= 0, got {self.factor}")
        if not (math.isfinite(self.distance) and self.distance >= 0):
            raise FaultError(f"fault land_drift: 'distance' must be >= 0 m, got {self.distance}")
        if not 0.0 <= self.level <= 1.0:
            raise FaultError(f"fault low_battery: 'level' must be within 0..1, got {self.level}")

    def applies(self, vehicle: str, t: float) -> bool:
        return (self.vehicle is None or self.vehicle == vehicle) and self.at <= t and (
            self.until is None or t < self.until
        )

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], where: str = "sim.faults[]") -> Fault:
        if not isinstance(d, Mapping):
            raise FaultError(f"{where}: a fault is a mapping like {{kind: dropout, vehicle: r3, at: 20}}")
        kind = d.get("kind")
        if kind not in KINDS:
            raise FaultError(f"{where}.kind: {kind!r} is not a fault kind; use one of {', '.join(KINDS)}")
        unknown = set(d) - _COMMON_KEYS - _KIND_KEYS[kind]
        if unknown:
            raise FaultError(f"{where}: unknown key(s) {sorted(unknown)} for a {kind} fault")
        kw: dict[str, Any] = {"kind": kind}
        if d.get("vehicle") is not None:
            kw["vehicle"] = str(d["vehicle"])
        for key in ("at", "until", "rate", "seconds", "factor", "level", "distance"):
            if key in d and d[key] is not None:
                val = d[key]
                if isinstance(val, bool) or not isinstance(val, int | float):
                    raise FaultError(f"{where}.{key}: expected a number, got {val!r}")
                kw[key] = float(val)
        if kind == "packet_loss" and "rate" not in kw:
            raise FaultError(f"{where}: a packet_loss fault needs 'rate' (0..1)")
        if kind == "latency" and "seconds" not in kw:
            raise FaultError(f"{where}: a latency fault needs 'seconds'")
        if kind == "battery_drain" and "factor" not in kw:
            raise FaultError(f"{where}: a battery_drain fault needs 'factor'")
        if kind == "land_drift" and "distance" not in kw:
            raise FaultError(f"{where}: a land_drift fault needs 'distance' (metres)")
        if kind == "low_battery" and "level" not in kw:
            raise FaultError(f"{where}: a low_battery fault needs 'level' (0..1)")
        try:
            return cls(**kw)
        except FaultError as exc:
            raise FaultError(f"{where}: {exc}") from None


class FaultBook:
    """The active set of faults, queried by the world (drain, arming) and the links (the rest)."""

    def __init__(self, faults: Iterable[Fault] = ()) -> None:
        self._faults: list[Fault] = list(faults)

    def __len__(self) -> int:
        return len(self._faults)

    def __iter__(self) -> Iterator[Fault]:
        return iter(list(self._faults))

    def add(self, fault: Fault) -> None:
        self._faults.append(fault)

    def remove(self, kind: str | None = None, vehicle: str | None = None) -> int:
        """Remove faults of ``kind`` (None = all kinds) scoped to exactly ``vehicle``
        (None = the fleet-wide ones, or every fault when kind is None too). Returns how many."""
        before = len(self._faults)
        if kind is None and vehicle is None:
            self._faults.clear()
        else:
            self._faults = [
                f for f in self._faults if not ((kind is None or f.kind == kind) and f.vehicle == vehicle)
            ]
        return before - len(self._faults)

    def _active(self, kind: str, vehicle: str, t: float) -> list[Fault]:
        return [f for f in self._faults if f.kind == kind and f.applies(vehicle, t)]

    def dropped(self, vehicle: str, t: float) -> bool:
        return bool(self._faults) and bool(self._active("dropout", vehicle, t))

    def loss_rate(self, vehicle: str, t: float) -> float:
        if not self._faults:
            return 0.0
        keep = 1.0
        for f in self._active("packet_loss", vehicle, t):
            keep *= 1.0 - f.rate
        return 1.0 - keep

    def latency(self, vehicle: str, t: float) -> float:
        if not self._faults:
            return 0.0
        return sum(f.seconds for f in self._active("latency", vehicle, t))

    def drain_factor(self, vehicle: str, t: float) -> float:
        if not self._faults:
            return 1.0
        factor = 1.0
        for f in self._active("battery_drain", vehicle, t):
            factor *= f.factor
        return factor

    def refuses_arm(self, vehicle: str, t: float) -> bool:
        return bool(self._faults) and bool(self._active("refuse_arm", vehicle, t))

    def rejects_mission(self, vehicle: str, t: float) -> bool:
        """The autopilot refuses every mission upload (MAV_MISSION_DENIED, with a STATUSTEXT reason)."""
        return bool(self._faults) and bool(self._active("reject_mission", vehicle, t))

    def no_gps(self, vehicle: str, t: float) -> bool:
        """GPS_RAW_INT reports no fix (fix_type 1)."""
        return bool(self._faults) and bool(self._active("no_gps", vehicle, t))

    def unhealthy(self, vehicle: str, t: float) -> bool:
        """The magnetometer is present but unhealthy in SYS_STATUS."""
        return bool(self._faults) and bool(self._active("unhealthy", vehicle, t))

    def drives_off(self, vehicle: str, t: float) -> bool:
        """The carrier drives on along its heading, deaf to its mission (``drive_off``)."""
        return bool(self._faults) and bool(self._active("drive_off", vehicle, t))

    def land_drift(self, vehicle: str, t: float) -> float:
        """Metres east a landing begun now drifts on its way down (``land_drift``; 0 without one)."""
        if not self._faults:
            return 0.0
        return sum(f.distance for f in self._active("land_drift", vehicle, t))

    def battery_level(self, vehicle: str, t: float) -> float | None:
        """The cap on the battery (0..1) of an active low_battery fault, None without one."""
        if not self._faults:
            return None
        levels = [f.level for f in self._active("low_battery", vehicle, t)]
        return min(levels) if levels else None
