"""Preflight checks: pure functions over a :class:`~fleetctl.mavlink.vehicle.Vehicle` proxy's state.

One :class:`PreflightRow` per vehicle lists every check (docs/field-safety.md):

* ``heartbeat`` - heard, and not lost;
* ``gps`` - GPS_RAW_INT ``fix_type`` 3D or better;
* ``home`` - a HOME_POSITION was received;
* ``sensors`` - every SYS_STATUS sensor that is present (and enabled, when the vehicle reports
  enabled bits) is healthy; the RC receiver is not required (the fleet flies over MAVLink);
* ``battery`` - above ``rovers.reserve``; a rover that is to deploy also needs the mission's
  ``deploy_range`` of flight on top of it (:func:`fleetctl.run.energy.range_from_percent`);
* ``disarmed`` - not armed and not airborne (skipped for ``fleetctl resume`` and ``collect``,
  whose rovers are in the air; a collection also leaves rovers' batteries to the planner).

``fleetctl status`` shows the rows; :func:`fleetctl.run.admission.admit` leaves failing rovers out
and stops the run when the carrier fails. Gathering the telemetry (and the link-loss failsafe
parameters) is :func:`fleetctl.run.safety.gather`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from fleetctl.mavlink.link import enum_name
from fleetctl.mavlink.vehicle import Vehicle
from fleetctl.mission import Mission
from fleetctl.run.energy import range_from_percent

M = mavlink2
CHECKS = ("heartbeat", "gps", "home", "sensors", "battery", "disarmed")
NOT_REQUIRED = M.MAV_SYS_STATUS_SENSOR_RC_RECEIVER
PREARM_TEXT_AGE = 60.0  # s: a "PreArm:" STATUSTEXT older than this no longer explains a failing check
_SENSOR_WORDS = {
    "3D_GYRO": "gyroscope", "3D_ACCEL": "accelerometer", "3D_MAG": "magnetometer",
    "ABSOLUTE_PRESSURE": "barometer", "GPS": "GPS", "AHRS": "attitude estimator",
    "MOTOR_OUTPUTS": "motor outputs", "BATTERY": "battery", "RC_RECEIVER": "RC receiver",
}
_FIX = {0: "no GPS", 1: "no fix", 2: "2D fix", 3: "3D fix", 4: "DGPS", 5: "RTK float", 6: "RTK fixed",
        7: "static", 8: "PPP"}


@dataclass(frozen=True)
class Check:
    name: str  # one of CHECKS
    ok: bool
    detail: str


@dataclass
class PreflightRow:
    vehicle: str
    role: str  # carrier | rover
    checks: list[Check] = field(default_factory=list)
    link_loss: str | None = None  # what the vehicle does if the link drops (safety.gather)
    warnings: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return all(c.ok for c in self.checks)

    @property
    def failures(self) -> list[str]:
        return [c.detail for c in self.checks if not c.ok]

    def check(self, name: str) -> Check | None:
        return next((c for c in self.checks if c.name == name), None)


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


def _prearm_text(v: Vehicle, within: float = PREARM_TEXT_AGE) -> str | None:
    """The vehicle's last "PreArm: …" STATUSTEXT (ArduPilot says there why it cannot arm yet)."""
    now = time.monotonic()
    return next((text for ts, _sev, text in reversed(v.statustexts)
                 if text.startswith("PreArm") and now - ts <= within), None)


def needs_deploy_range(mission: Mission, command: str | None) -> bool:
    """Do the rovers need ``deploy_range`` of battery for ``command`` (None = ``fleetctl status``:
    yes when the mission has tasks)?"""
    if command is None:
        return bool(mission.tasks)
    return command in ("deploy", "run")


def check_vehicle(v: Vehicle, mission: Mission, *, carrier: bool, command: str | None = None,
                  resuming: bool = False) -> PreflightRow:
    """Every check of one vehicle (see the module docstring)."""
    row = PreflightRow(v.name, "carrier" if carrier else "rover")
    add = row.checks.append
    if not v.connected:
        add(Check("heartbeat", False, "no heartbeat"))
        return row
    add(Check("heartbeat", not v.lost, "link lost (no heartbeat)" if v.lost else "ok"))
    fix = v.gps_fix_type
    if fix is None:
        add(Check("gps", False, "no GPS_RAW_INT received (GPS fix unknown)"))
    else:
        sats = "" if v.gps_satellites is None else f", {v.gps_satellites} satellites"
        words = _FIX.get(fix, f"fix type {fix}")
        add(Check("gps", fix >= M.GPS_FIX_TYPE_3D_FIX,
                  f"{words}{sats}" if fix >= M.GPS_FIX_TYPE_3D_FIX else f"GPS {words}{sats}: needs a 3D fix"))
    add(Check("home", v.home is not None, "ok" if v.home is not None else "home position unknown "
              "(no HOME_POSITION received)"))
    bad = unhealthy_sensors(v)
    if v.sensors_present is None:
        add(Check("sensors", False, "no SYS_STATUS received (sensor health unknown)"))
    else:
        prearm = _prearm_text(v) if bad else None
        detail = "sensors not healthy: " + ", ".join(bad) + (f" ({prearm})" if prearm else "")
        add(Check("sensors", not bad, "ok" if not bad else detail))
    in_field = command == "collect"  # rovers wait in the air where the deployment left them
    if carrier or not in_field:  # a rover's range decides whether it is collected, not preflight
        add(_battery(v, mission, carrier, command))
    if not resuming and not in_field:
        airborne = v.on_ground is False
        busy = "armed" if v.armed else ("airborne" if airborne else None)
        add(Check("disarmed", busy is None, "ok" if busy is None else f"already {busy}"))
    return row


def _battery(v: Vehicle, mission: Mission, carrier: bool, command: str | None) -> Check:
    rp = mission.rovers
    pct = v.battery_pct
    if pct is None:
        return Check("battery", False, "battery level unknown (no BATTERY_STATUS/SYS_STATUS)")
    if pct / 100.0 <= rp.reserve:
        return Check("battery", False, f"battery {pct:.0f} % is not above the reserve {rp.reserve:.0%}")
    if not carrier and needs_deploy_range(mission, command):
        rng = range_from_percent(pct, rp.reserve, rp.endurance_range) or 0.0
        if rng < rp.deploy_range:
            need = 100.0 * (rp.reserve + rp.deploy_range / rp.endurance_range)
            return Check("battery", False, f"battery {pct:.0f} % gives {rng:.0f} m above the reserve, "
                         f"less than the deploy range {rp.deploy_range:g} m (needs {need:.0f} %)")
    return Check("battery", True, f"{pct:.0f} %")


def check_fleet(fleet_vehicles: dict[str, Vehicle], carrier_id: str, mission: Mission, *,
                command: str | None = None, resuming: bool = False) -> dict[str, PreflightRow]:
    """vehicle id -> its row, for every vehicle given (carrier first as in the fleet)."""
    return {vid: check_vehicle(v, mission, carrier=vid == carrier_id, command=command, resuming=resuming)
            for vid, v in fleet_vehicles.items()}


__all__ = ["CHECKS", "Check", "PreflightRow", "check_fleet", "check_vehicle", "needs_deploy_range",
           "unhealthy_sensors"]
