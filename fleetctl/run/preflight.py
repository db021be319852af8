"""Preflight checks: pure functions over a :class:`~fleetctl.mavlink.vehicle.Vehicle` proxy's state.

One :class:`PreflightRow` per vehicle lists every check (docs/field-safety.md):

* ``heartbeat`` - heard, and not lost;
* ``system`` - HEARTBEAT ``system_status`` is not EMERGENCY, POWEROFF or FLIGHT_TERMINATION
  (CRITICAL, an autopilot failsafe, is a warning);
* ``gps`` - GPS_RAW_INT ``fix_type`` 3D or better;
* ``position`` - a GLOBAL_POSITION_INT was received;
* ``home`` - a HOME_POSITION was received;
* ``sensors`` - every SYS_STATUS sensor that is present (and enabled, when the vehicle reports
  enabled bits) is healthy; the RC receiver is not required (the fleet flies over MAVLink);
* ``battery`` - above ``rovers.reserve``; a rover that is to deploy is planned with the range its
  battery gives (:func:`fleetctl.run.energy.range_from_percent`), at most ``deploy_range``: it
  fails only when that range reaches no task of the mission (:func:`min_reach`);
* ``disarmed`` - not armed and not airborne (skipped for ``fleetctl resume`` and ``collect``,
  whose rovers are in the air; a collection also leaves rovers' batteries to the planner).

The failures of a row are in the order of ``CHECKS``, so the first is the real reason (a vehicle
that does not answer fails ``heartbeat`` alone). ``fleetctl status`` (:func:`check_connected`, shown
by :mod:`fleetctl.views.status`) and every flying command (:func:`fleetctl.run.admission.admit`
through :func:`fleetctl.run.safety.admit_safety`) run these same checks; admission leaves failing
rovers out and stops the run when the carrier fails. Gathering the telemetry (and the link-loss failsafe
parameters) is :func:`fleetctl.run.safety.gather`.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass, field

from fleetctl.mavlink.fleet import Fleet
from fleetctl.mavlink.health import (
    STATE_CRITICAL,
    STATE_FAILING,
    fix_words,
    has_3d_fix,
    prearm_text,
    state_words,
    unhealthy_sensors,
)
from fleetctl.mavlink.vehicle import Vehicle
from fleetctl.mission import Mission
from fleetctl.mission.flight import TAKEOFF_HEIGHT
from fleetctl.run.energy import range_from_percent

CHECKS = ("heartbeat", "system", "gps", "position", "home", "sensors", "battery", "disarmed")


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
    range: float | None = None  # m: a deploying rover's planning range (its battery's, at most deploy_range)

    @property
    def ok(self) -> bool:
        return all(c.ok for c in self.checks)

    @property
    def failures(self) -> list[str]:
        return [c.detail for c in self.checks if not c.ok]

    def check(self, name: str) -> Check | None:
        return next((c for c in self.checks if c.name == name), None)


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
    add(_system(v, row))
    fix = v.gps_fix_type
    if fix is None:
        add(Check("gps", False, "no GPS_RAW_INT received (GPS fix unknown)"))
    else:
        sats = "" if v.gps_satellites is None else f", {v.gps_satellites} satellites"
        words, ok = fix_words(fix), has_3d_fix(fix)
        add(Check("gps", ok, f"{words}{sats}" if ok else f"GPS {words}{sats}: needs a 3D fix"))
    add(Check("position", v.position is not None, "ok" if v.position is not None else
              "no position (GLOBAL_POSITION_INT) received"))
    add(Check("home", v.home is not None, "ok" if v.home is not None else "home position unknown "
              "(no HOME_POSITION received)"))
    bad = unhealthy_sensors(v)
    if v.sensors_present is None:
        add(Check("sensors", False, "no SYS_STATUS received (sensor health unknown)"))
    else:
        prearm = prearm_text(v) if bad else None
        detail = "sensors not healthy: " + ", ".join(bad) + (f" ({prearm})" if prearm else "")
        add(Check("sensors", not bad, "ok" if not bad else detail))
    in_field = command == "collect"  # rovers wait in the air where the deployment left them
    if carrier or not in_field:  # a rover's range decides whether it is collected, not preflight
        add(_battery(v, mission, carrier, command, row))
    if not resuming and not in_field:
        airborne = v.on_ground is False
        busy = "armed" if v.armed else ("airborne" if airborne else None)
        add(Check("disarmed", busy is None, "ok" if busy is None else f"already {busy}"))
    return row


def _system(v: Vehicle, row: PreflightRow) -> Check:
    st = v.system_status
    if st is None:
        return Check("system", True, "unknown")
    words = state_words(st)
    if st == STATE_CRITICAL:
        row.warnings.append("system status critical (an autopilot failsafe is active)")
    if st in STATE_FAILING:
        return Check("system", False, f"system status {words} (MAV_STATE {st})")
    return Check("system", True, words)


def min_reach(mission: Mission) -> float:
    """Metres of flight the nearest task needs at least: a rover climbs ``TAKEOFF_HEIGHT`` above
    the deck and flies its line from there, so with the carrier right under a task at height ``z``
    the flight is ``|z - TAKEOFF_HEIGHT|`` (the planners' lifted task, planners.core.approach)."""
    return min((abs(t.position[2] - TAKEOFF_HEIGHT) for t in mission.tasks), default=0.0)


def planning_range(v: Vehicle, mission: Mission) -> float | None:
    """The range a deploying rover is planned with: what its battery gives above the reserve, at
    most the mission's ``deploy_range`` (None when its battery level is unknown)."""
    rp = mission.rovers
    rng = range_from_percent(v.battery_pct, rp.reserve, rp.endurance_range)
    return None if rng is None else min(rng, rp.deploy_range)


def _battery(v: Vehicle, mission: Mission, carrier: bool, command: str | None, row: PreflightRow) -> Check:
    rp = mission.rovers
    pct = v.battery_pct
    if pct is None:
        return Check("battery", False, "battery level unknown (no BATTERY_STATUS/SYS_STATUS)")
    if pct / 100.0 <= rp.reserve:
        return Check("battery", False, f"battery {pct:.0f} % is not above the reserve {rp.reserve:.0%}")
    if not carrier and needs_deploy_range(mission, command):
        rng = range_from_percent(pct, rp.reserve, rp.endurance_range) or 0.0
        row.range = min(rng, rp.deploy_range)
        if rng < rp.deploy_range:
            need = 100.0 * (rp.reserve + rp.deploy_range / rp.endurance_range)
            gives = (f"battery {pct:.0f} % gives {rng:.0f} m above the reserve, less than the deploy range "
                     f"{rp.deploy_range:g} m (needs {need:.0f} %)")
            reach = min_reach(mission)
            if rng < reach:
                return Check("battery", False, f"{gives}: it reaches no task "
                             f"(the nearest needs {reach:.1f} m)")
            return Check("battery", True, f"{gives}: planned with {rng:.0f} m, flies only tasks it reaches")
    return Check("battery", True, f"{pct:.0f} %")


def check_connected(fleet: Fleet, mission: Mission, *, command: str | None = None, resuming: bool = False
                    ) -> dict[str, PreflightRow]:
    """:func:`check_fleet` over every vehicle of ``fleet``, including those that did not answer:
    their one failing check is ``heartbeat``, saying what their link heard
    (:meth:`fleetctl.mavlink.fleet.Fleet.failure_line`)."""
    rows = check_fleet(fleet.vehicles, fleet.carrier_ids, mission, command=command, resuming=resuming)
    for vid, v in fleet.vehicles.items():
        if not v.connected:
            why = fleet.errors.get(vid, "no heartbeat")
            heard = fleet.silence.get(vid)
            rows[vid].checks[:] = [Check("heartbeat", False, why + (f"; {heard}" if heard else ""))]
    return rows


def check_fleet(fleet_vehicles: dict[str, Vehicle], carriers: str | Collection[str], mission: Mission, *,
                command: str | None = None, resuming: bool = False) -> dict[str, PreflightRow]:
    """vehicle id -> its row, for every vehicle given (carrier first as in the fleet); ``carriers``:
    the carrier's id, or every carrier's (several teams)."""
    ids = {carriers} if isinstance(carriers, str) else set(carriers)
    return {vid: check_vehicle(v, mission, carrier=vid in ids, command=command, resuming=resuming)
            for vid, v in fleet_vehicles.items()}


__all__ = ["CHECKS", "Check", "PreflightRow", "check_connected", "check_fleet", "check_vehicle", "min_reach",
           "needs_deploy_range", "planning_range"]
