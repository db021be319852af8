"""Field safety before arming (docs/field-safety.md): the telemetry preflight needs, the link-loss
failsafe (read, described, set by ``links.failsafe``), the geofence (uploaded as a FENCE mission
with its parameters) and the check that plans stay inside it.

:func:`admit_safety` is what :func:`fleetctl.run.admission.admit` calls: a rover that fails
preflight (or refuses its failsafe/fence setup) is left out of the run - like a rover that did not
answer - and a carrier that fails stops the run with an :class:`ExecutionError`.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from shapely.geometry import LineString, Point, Polygon

from fleetctl.geo import Origin
from fleetctl.mavlink.autopilots import ModeError
from fleetctl.mavlink.fence import fence_items as mavlink_fence_items
from fleetctl.mavlink.fleet import Fleet
from fleetctl.mavlink.health import request_missing, unhealthy_sensors
from fleetctl.mavlink.link import LinkError, MissionItem
from fleetctl.mavlink.params import ParamError, read_params, set_param
from fleetctl.mavlink.vehicle import CommandRejected, Vehicle
from fleetctl.mission import Mission
from fleetctl.mission.model import GeofenceConfig
from fleetctl.run.context import ExecutionError
from fleetctl.run.firmware_speeds import apply_firmware_speeds
from fleetctl.run.kinds import Ev
from fleetctl.run.preflight import PreflightRow, check_connected, check_fleet

GATHER_TIMEOUT = 3.0  # s to wait for the telemetry preflight checks read
# s a vehicle failing preflight on sensor health alone is given to report its sensors healthy: PX4 SITL's
# rover carrier reported "xy position control" unhealthy in one SYS_STATUS seconds after `fleetctl status`
# had found every sensor healthy, and a carrier failing preflight stops the run
SENSOR_SETTLE = 3.0
RTL_WARNING = ("RTL returns a rover to where it armed: a carrier stop the carrier will have left "
               "(set links.failsafe: hold or land to keep rovers near their task)")


def _complete(v: Vehicle) -> bool:
    return (v.position is not None and v.battery_pct is not None and v.landed_state is not None
            and v.gps_fix_type is not None and v.sensors_present is not None and v.home is not None)


async def gather(fleet: Fleet, timeout: float = GATHER_TIMEOUT, vehicles: list[Vehicle] | None = None
                 ) -> dict[str, PreflightFailsafe]:
    """Wait (up to ``timeout`` s) for the telemetry the checks read - asking for HOME_POSITION,
    GPS_RAW_INT and SYS_STATUS once - and read every vehicle's link-loss parameters."""
    todo = [v for v in (vehicles or list(fleet.vehicles.values())) if v.connected]

    await gather_telemetry(todo, timeout)
    return await read_failsafes(todo)


async def gather_telemetry(vehicles: list[Vehicle], timeout: float = GATHER_TIMEOUT) -> None:
    """Wait for what the checks read, asking once (REQUEST_MESSAGE) for what has not come yet."""
    async def one(v: Vehicle) -> None:
        if _complete(v):
            return
        with contextlib.suppress(LinkError, CommandRejected, TimeoutError):
            async with asyncio.timeout(timeout):
                await request_missing(v)
                await v.wait_until(_complete, timeout, "preflight telemetry")

    await asyncio.gather(*(one(v) for v in vehicles if v.connected and not v.lost))


async def settle_sensors(vehicles: dict[str, Vehicle], rows: dict[str, PreflightRow],
                         timeout: float = SENSOR_SETTLE) -> bool:
    """Wait up to ``timeout`` for the vehicles whose only failing check is sensor health to report
    every sensor healthy (a health flag that flickers is not a failed sensor; one that stays
    unhealthy fails as before). Returns whether any vehicle was waited for (check again)."""
    waiting = [vehicles[vid] for vid, row in rows.items()
               if vid in vehicles and {c.name for c in row.checks if not c.ok} == {"sensors"}]

    async def one(v: Vehicle) -> None:
        with contextlib.suppress(TimeoutError):
            await v.wait_until(lambda v: v.lost or not unhealthy_sensors(v), timeout, "sensors healthy")

    await asyncio.gather(*(one(v) for v in waiting))
    return bool(waiting)


async def read_failsafes(vehicles: list[Vehicle]) -> dict[str, PreflightFailsafe]:
    got = await asyncio.gather(*(read_failsafe(v) for v in vehicles))
    return {v.name: fs for v, fs in zip(vehicles, got, strict=True)}


@dataclass
class PreflightFailsafe:
    """What one vehicle does on link loss, from its parameters."""

    params: dict[str, float | None]
    action: str | None  # generic (none, hold, land, rtl, continue ..., terminate), None = unknown
    text: str  # "link loss: RTL after 10 s"


async def read_failsafe(v: Vehicle) -> PreflightFailsafe:
    ap = v.autopilot
    if ap is None or not ap.failsafe_param_names:
        return PreflightFailsafe({}, None, "link loss: unknown (no failsafe parameters for this autopilot)")
    params = await read_params(v, list(ap.failsafe_param_names), timeout=0.5, retries=2)
    return PreflightFailsafe(params, ap.failsafe_action(params), ap.describe_failsafe(params))


def rtl_on_link_loss(fs: PreflightFailsafe) -> bool:
    """Does the vehicle return to launch when its link is lost (a rover: :data:`RTL_WARNING`)?"""
    return fs.action is not None and "rtl" in fs.action.lower()


async def status_preflight(fleet: Fleet, mission: Mission, timeout: float) -> dict[str, PreflightRow]:
    """``fleetctl status``: every vehicle's preflight row (the checks every flying command runs)
    with its link-loss failsafe and, for a rover that returns to launch on link loss, the RTL
    warning. Waits at most ``timeout`` (and :data:`GATHER_TIMEOUT`) s for the telemetry."""
    failsafe = await gather(fleet, min(timeout, GATHER_TIMEOUT))
    rows = check_connected(fleet, mission)
    for vid, fs in failsafe.items():
        rows[vid].link_loss = fs.text
        if vid not in fleet.carrier_ids and rtl_on_link_loss(fs):
            rows[vid].warnings.append(f"link loss {fs.text.removeprefix('link loss: ')}: {RTL_WARNING}")
    return rows


async def set_failsafe(v: Vehicle, action: str,
                       current: PreflightFailsafe | None = None) -> PreflightFailsafe:
    """Set the link-loss action (``links.failsafe``: hold | land | rtl) and read it back."""
    ap = v.autopilot
    if ap is None:
        raise ParamError(f"{v.name}: no heartbeat, cannot set its failsafe")
    values = ap.failsafe_params(action, current.params if current else None)
    for name, value in values.items():
        await set_param(v, name, value)
    return await read_failsafe(v)


# ------------------------------------------------------------------------------------- geofence
def fence_items(fence: GeofenceConfig, origin: Origin) -> list[MissionItem]:
    """The mission's geofence as a FENCE mission (:func:`fleetctl.mavlink.fence.fence_items`):
    the inclusion polygon, then one exclusion polygon per obstacle."""
    return mavlink_fence_items(fence.polygon, fence.exclusions, origin)


async def upload_fence(v: Vehicle, fence: GeofenceConfig, origin: Origin) -> None:
    """Upload the fence (MAVLink mission protocol, mission_type FENCE), then enable it with its
    height limit and breach action (the autopilot's parameters)."""
    await v.upload_fence(fence_items(fence, origin))
    if v.autopilot is None:
        raise ParamError(f"{v.name}: no heartbeat")
    for name, value in v.autopilot.fence_params(fence.alt_max, fence.action).items():
        await set_param(v, name, value)


async def download_fence(v: Vehicle) -> list[MissionItem]:
    return await v.download_fence()


def plan_violations(plan: Any, fence: GeofenceConfig) -> list[str]:
    """Where a plan (:class:`planners.core.plan.Plan`) leaves the geofence: carrier stops and paths,
    rover paths (also through an exclusion zone, or above ``alt_max``)."""
    inc = Polygon(fence.polygon).buffer(1e-6)
    exc = [(j, Polygon(p)) for j, p in enumerate(fence.exclusions)]
    out: list[str] = []

    def shape(path: list[Any]) -> Any:
        pts = [(float(p[0]), float(p[1])) for p in path]
        return Point(pts[0]) if len(set(pts)) < 2 else LineString(pts)

    def crossing(g: Any) -> int | None:
        for j, e in exc:
            inter = g.intersection(e)
            if (inter.length > 1e-3) if isinstance(g, LineString) else e.contains(g):
                return j
        return None

    for i, stop in enumerate(plan.stops):
        x, y = stop.position[0], stop.position[1]
        if not inc.covers(Point(x, y)):
            out.append(f"carrier stop {i + 1} at ({x:.1f}, {y:.1f}) is outside the geofence")
        if len(stop.carrier_path) >= 1:
            g = shape(stop.carrier_path)
            if not inc.covers(g):
                out.append(f"the carrier's path to stop {i + 1} leaves the geofence")
            j = crossing(g)
            if j is not None:
                out.append(f"the carrier's path to stop {i + 1} crosses exclusion zone obstacles[{j}]")
        for leg in stop.rovers:
            to = f" to task {leg.task}" if leg.task else ""
            what = f"rover {leg.rover}'s path{to} (stop {i + 1})"
            g = shape(leg.path)
            if not inc.covers(g):
                out.append(f"{what} leaves the geofence")
            j = crossing(g)
            if j is not None:
                out.append(f"{what} crosses exclusion zone obstacles[{j}]")
            top = max(float(p[2]) for p in leg.path) if leg.path else 0.0
            if fence.alt_max is not None and top > fence.alt_max + 1e-6:
                out.append(f"{what} climbs to {top:.1f} m, above the geofence alt_max {fence.alt_max:g} m")
    return out


def line_clear(mission: Mission, a: Sequence[float], b: Sequence[float]) -> bool:
    """The straight line ``a`` -> ``b`` (ENU; its ground projection) touches none of the mission's
    obstacles and stays inside its geofence, if it has one."""
    fence = mission.geofence
    if not mission.obstacles and fence is None:
        return True
    line = LineString([(float(a[0]), float(a[1])), (float(b[0]), float(b[1]))])
    zones = [*mission.obstacles, *(fence.exclusions if fence is not None else ())]
    if any(line.intersects(Polygon(z)) for z in zones):
        return False
    return fence is None or Polygon(fence.polygon).covers(line)


def check_plan(plan: Any, fence: GeofenceConfig | None) -> None:
    """Raise :class:`ExecutionError` naming every stop/rover of ``plan`` outside ``fence``."""
    if fence is None:
        return
    bad = plan_violations(plan, fence)
    if bad:
        raise ExecutionError(f"the {plan.kind} plan ({plan.planner}) leaves the geofence: " + "; ".join(bad)
                             + "; widen the geofence or move the tasks")


# ------------------------------------------------------------------------------------- admission
@dataclass
class SafetyReport:
    rows: dict[str, PreflightRow] = field(default_factory=dict)
    left_out: dict[str, str] = field(default_factory=dict)  # rover -> why it does not fly
    notes: list[tuple[str, str, str | None]] = field(default_factory=list)  # (kind, text, vehicle)
    mission: Mission | None = None  # the mission to plan with, when the firmware's handling changed it


def prefetch_failsafes(fleet: Fleet) -> asyncio.Task[dict[str, PreflightFailsafe]]:
    """Start reading every answering vehicle's link-loss parameters now (they take a moment from a
    vehicle that has gone quiet): pass the task to :func:`admit_safety`."""
    vehicles = [v for v in fleet.vehicles.values() if v.connected and not v.lost]
    return asyncio.ensure_future(read_failsafes(vehicles))


async def admit_safety(fleet: Fleet, mission: Mission, command: str, *, resuming: bool = False,
                       timeout: float = GATHER_TIMEOUT,
                       prefetched: asyncio.Task[dict[str, PreflightFailsafe]] | None = None) -> SafetyReport:
    """Preflight every answering vehicle, set ``links.failsafe`` and upload the geofence. Failing
    rovers are left out (``fleet.leave_out``) - unless resuming and airborne: then only a warning;
    a failing carrier raises :class:`ExecutionError`."""
    rep = SafetyReport()
    vehicles = {vid: v for vid, v in fleet.vehicles.items() if v.connected}
    await gather_telemetry(list(vehicles.values()), timeout)
    rep.rows = check_fleet(vehicles, fleet.carrier_id, mission, command=command, resuming=resuming)
    if await settle_sensors(vehicles, rep.rows):
        rep.rows = check_fleet(vehicles, fleet.carrier_id, mission, command=command, resuming=resuming)
    if prefetched is not None:
        failsafe = await prefetched
    else:
        failsafe = await read_failsafes([v for v in vehicles.values() if not v.lost])
    for vid, row in rep.rows.items():
        row.link_loss = failsafe[vid].text if vid in failsafe else None
        if not row.ok:
            _fail(fleet, rep, vid, "failed preflight: " + "; ".join(row.failures), resuming)
            continue
        for w in row.warnings:  # a critical system status
            rep.notes.append((Ev.PREFLIGHT_WARNING, f"{vid}: {w}", vid))
        battery = row.check("battery")
        if row.range is not None and row.range < mission.rovers.deploy_range and battery is not None:
            rep.notes.append((Ev.PREFLIGHT_WARNING, f"{vid}: {battery.detail}", vid))
    action = mission.links.failsafe
    for vid, v in vehicles.items():
        if vid in rep.left_out:
            continue
        fs = failsafe.get(vid)
        if action != "keep":
            try:
                fs = await set_failsafe(v, action, fs)
            except (ParamError, ModeError, LinkError) as exc:
                _fail(fleet, rep, vid, f"links.failsafe {action} not set: {exc}", resuming)
                continue
            rep.notes.append((Ev.FAILSAFE_SET, f"{vid}: {fs.text} (links.failsafe: {action})", vid))
        elif fs is not None:
            rep.notes.append((Ev.FAILSAFE, f"{vid}: {fs.text}", vid))
        if fs is not None:
            rep.rows[vid].link_loss = fs.text
            if vid != fleet.carrier_id and rtl_on_link_loss(fs):
                rep.rows[vid].warnings.append(RTL_WARNING)
                rep.notes.append((Ev.FAILSAFE_WARNING, f"{vid}: link loss {fs.action}: {RTL_WARNING}", vid))
    await _set_speeds(fleet, mission, rep, [vid for vid in vehicles if vid not in rep.left_out], resuming)
    fence = mission.geofence
    if fence is not None and mission.origin is not None:
        for vid, v in vehicles.items():
            if vid in rep.left_out:
                continue
            try:
                await upload_fence(v, fence, mission.origin)
            except (ParamError, ModeError, LinkError) as exc:
                _fail(fleet, rep, vid, f"geofence not uploaded: {exc}", resuming)
                continue
            rep.notes.append((Ev.GEOFENCE, f"{vid}: geofence uploaded ({len(fence.polygon)} vertices, "
                              f"{len(fence.exclusions)} exclusion zones, alt_max "
                              f"{'-' if fence.alt_max is None else f'{fence.alt_max:g} m'}, "
                              f"action {fence.action})", vid))
            if fence.action == "rtl" and vid != fleet.carrier_id:
                rep.notes.append((Ev.GEOFENCE_WARNING, f"{vid}: geofence action rtl: {RTL_WARNING}", vid))
    return rep


async def _set_speeds(fleet: Fleet, mission: Mission, rep: SafetyReport, vids: list[str],
                      resuming: bool) -> None:
    """``firmware_speeds: set``: the mission's speeds on the autopilots (fleetctl.run.firmware_speeds)."""
    speeds = await apply_firmware_speeds(fleet, mission, vids)
    for vid, why in speeds.failed.items():
        _fail(fleet, rep, vid, f"firmware speeds not set: {why}", resuming)
    for vid, written in speeds.written.items():
        text = ", ".join(f"{k} {v:g}" for k, v in written.items()) or "none of its speed parameters found"
        rep.notes.append((Ev.FIRMWARE_SPEEDS, f"{vid}: speeds set ({text})", vid))
    if speeds.mission is not None:
        r = speeds.mission.rovers
        rep.mission = speeds.mission
        accel = "-" if r.accel is None else f"{r.accel:.2f} m/s²"
        c = speeds.mission.carrier
        carrier = "" if c.accel is None else f"; carrier legs at {c.accel:.2f} m/s²"
        carrier += "" if c.turn_rate is None else f", turns at {c.turn_rate:.2f} rad/s"
        text = (f"planned with the firmware's handling: rovers take off in {r.takeoff_time:.1f} s, "
                f"touch down in {r.land_time:.1f} s, legs at {accel}{carrier}")
        rep.notes.append((Ev.FIRMWARE_SPEEDS, text, None))


def _fail(fleet: Fleet, rep: SafetyReport, vid: str, why: str, resuming: bool) -> None:
    if vid == fleet.carrier_id:
        raise ExecutionError(f"the carrier {vid} at {fleet.urls.get(vid, '?')} {why}; fix it before flying")
    v = fleet.vehicles[vid]
    if resuming and (v.armed or v.on_ground is False):  # flying its mission: keep it, say so
        rep.notes.append((Ev.PREFLIGHT_WARNING, f"{vid}: {why} (flying: kept)", vid))
        return
    rep.left_out[vid] = why
    fleet.leave_out(vid, why)


__all__ = ["RTL_WARNING", "PreflightFailsafe", "SafetyReport", "admit_safety", "check_plan", "download_fence",
           "fence_items", "gather", "gather_telemetry", "plan_violations", "prefetch_failsafes",
           "read_failsafe", "read_failsafes", "rtl_on_link_loss", "set_failsafe", "status_preflight",
           "upload_fence"]
