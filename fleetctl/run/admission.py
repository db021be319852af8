"""Before anything is armed: which vehicles fly, and whether this controller may fly them.

* **Fly with what answers.** The runner connects without requiring every vehicle; the carrier
  must answer, and so must at least as many rovers as there are tasks (deployment). A rover that
  does not answer is journalled (``missing``), shown, and summarised as lost with the reason.
  ``require_all`` (``--require-all``) restores the strict check.
* **One controller per fleet.** Another ground station's heartbeat on a link, or a vehicle that is
  already armed or flying a mission, means someone else is (or was) in control: refuse, naming
  what was seen, and point to ``fleetctl resume`` or ``--force``. ``fleetctl resume`` (it takes
  over its own interrupted run) and ``collect`` (its rovers wait in the air where a deployment
  left them) expect armed vehicles and check only for other ground stations.
* **Preflight** (:mod:`fleetctl.run.safety`, :mod:`fleetctl.run.preflight`): a rover that fails
  (GPS, home, sensors, battery, already armed) is left out like one that did not answer
  (``adm.left_out``); a failing carrier stops the run. ``links.failsafe`` and the geofence are set
  on every vehicle that flies.
* **Arming real aircraft is a decision.** ``confirm`` (from the command line, on a terminal) is
  shown what will be armed and must say yes.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from fleetctl.mavlink.fleet import CONNECT_HINT, Fleet
from fleetctl.mavlink.vehicle import Vehicle
from fleetctl.mission import Mission
from fleetctl.run.context import ExecutionError
from fleetctl.run.safety import admit_safety, prefetch_failsafes

GCS_LISTEN = 1.5  # s after the links opened to listen for another ground station's 1 Hz heartbeat
IN_MISSION_MODES = ("MISSION", "TAKEOFF", "GUIDED", "LAND", "RTL")


@dataclass
class Admission:
    require_all: bool = False
    force: bool = False  # fly even if another controller seems to be in charge
    resuming: bool = False
    confirm: Callable[[list[str]], bool] | None = None  # shown what will be armed; True = go
    opened: float = 0.0  # time.monotonic() when the links were opened
    left_out: dict[str, str] = field(default_factory=dict)  # set by admit: rovers failing preflight -> why
    safety: Any = None  # set by admit: the fleetctl.run.safety.SafetyReport


def _rovers_needed(mission: Mission) -> int:
    """Rovers a deployment needs: one per task; a long operation's rovers fly several sorties."""
    return 1 if mission.operation else len(mission.tasks)


async def admit(fleet: Fleet, mission: Mission, command: str, adm: Admission) -> dict[str, str]:
    """Check the connected fleet (see the module docstring); returns the missing rovers -> why.
    Raises :class:`ExecutionError` when the run must not go ahead."""
    missing = {vid: fleet.errors.get(vid, "no heartbeat") for vid in fleet.missing()}
    carrier = fleet.carrier_id
    lines = "".join(f"\n  {fleet.failure_line(vid)}" for vid in missing)  # one short line per vehicle
    if carrier in missing:
        raise ExecutionError(f"the carrier did not answer ({CONNECT_HINT}):\n  {fleet.failure_line(carrier)}")
    if missing and adm.require_all:
        raise ExecutionError(f"{len(missing)} vehicle(s) did not answer (--require-all; "
                             f"{CONNECT_HINT}):{lines}")
    answered = len(fleet.rovers) - len(missing)
    if command in ("deploy", "run") and answered < _rovers_needed(mission):
        raise ExecutionError(f"only {answered} rover(s) answered for {len(mission.tasks)} tasks "
                             f"({CONNECT_HINT}):{lines}")
    params = prefetch_failsafes(fleet)  # read while listening for another controller
    try:
        if not adm.force:
            # a collection finds its rovers in the air and the carrier where the deployment left it
            await _one_controller(fleet, adm.resuming or command == "collect", adm.opened)
        adm.safety = await admit_safety(fleet, mission, command, resuming=adm.resuming, prefetched=params)
    finally:
        params.cancel()
    adm.left_out = dict(adm.safety.left_out)
    failed = "; ".join(f"{vid} ({why})" for vid, why in adm.left_out.items())
    if adm.left_out and adm.require_all:
        raise ExecutionError(f"{len(adm.left_out)} rover(s) failed preflight (--require-all): {failed}")
    passed = answered - len(adm.left_out)
    if command in ("deploy", "run") and not adm.resuming and passed < _rovers_needed(mission):
        raise ExecutionError(f"only {passed} rover(s) passed preflight for "
                             f"{len(mission.tasks)} tasks; failed: {failed}")
    if adm.confirm is not None:
        ok = await asyncio.to_thread(adm.confirm, arming_lines(fleet))
        if not ok:
            raise ExecutionError("not confirmed: nothing was armed")
    return missing


async def _one_controller(fleet: Fleet, armed_expected: bool, opened: float) -> None:
    listen = max(0.0, opened + GCS_LISTEN - time.monotonic())  # connecting took most of it already
    with contextlib.suppress(TimeoutError):  # heartbeats of another ground station, if any
        async with asyncio.timeout(listen):
            while not any(link.other_ground_stations() for link in fleet.links.values()):
                await asyncio.sleep(0.1)
    seen = [f"ground station {s}/{c} on {url}" for url, link in fleet.links.items()
            for s, c in link.other_ground_stations()]
    if not armed_expected:
        seen += [f"{v.name} is {what}" for v in fleet.vehicles.values() if v.connected
                 for what in [_busy(v)] if what]
    if seen:
        raise ExecutionError("another controller is (or was) in charge of this fleet: " + "; ".join(seen)
                             + ". If it was this mission's controller and it died, finish the run with "
                             "'fleetctl resume --run DIR'; to fly anyway, pass --force")


def _busy(v: Vehicle) -> str | None:
    if v.armed:
        return f"armed (mode {v.mode_firmware or v.mode or '?'})"
    if v.mode in IN_MISSION_MODES and v.on_ground is False:
        return f"flying in {v.mode}"
    return None


def arming_lines(fleet: Fleet) -> list[str]:
    """One line per vehicle that may be armed: id, role, system id, link, battery."""
    out = []
    for vid, v in fleet.vehicles.items():
        if not v.connected:
            continue
        role = "carrier" if vid == fleet.carrier_id else "rover"
        batt = f"{v.battery_pct:.0f} %" if v.battery_pct is not None else "battery ?"
        out.append(f"{vid:<10} {role:<8} sysid {v.sysid:<4} {fleet.urls.get(vid, ''):<28} {batt}")
    return out


__all__ = ["Admission", "admit", "arming_lines"]
