"""What ``fleetctl status`` shows of the preflight (:mod:`fleetctl.run.preflight`), three ways:

* on a terminal, a table (failing rows in red);
* without one (piped, CI), :func:`plain_lines`: a header line and one tab-separated line per
  vehicle, every cell whole;
* with ``--json``, :func:`json_objects`: one JSON object per vehicle and line, with every check.

The checks and the verdict come from the preflight module; this module only adds what a person
reading the preflight wants to see beside them (link age, mode, GPS, position, deck).
"""

from __future__ import annotations

import json
import sys
from typing import IO, Any

from fleetctl.geo import Origin, geodetic_to_enu
from fleetctl.mavlink.fleet import CONNECT_HINT, Fleet
from fleetctl.mavlink.vehicle import Vehicle
from fleetctl.mission import Mission
from fleetctl.run.preflight import PreflightRow

DECK_RADIUS = 1.5  # m: a landed rover this close (horizontally) to the carrier is on its deck
COLUMNS = [("id", "vehicle"), ("role", "role"), ("sysid", "sysid"), ("url", "connection"),
           ("link", "link"), ("autopilot", "autopilot"), ("armed", "armed"), ("mode", "mode"),
           ("battery", "battery"), ("gps", "GPS"), ("position", "position E, N, U m"), ("deck", "deck"),
           ("link_loss", "link loss"), ("ready", "ready"), ("reasons", "why not ready")]


def on_deck(v: Vehicle, carrier: Vehicle) -> bool | None:
    """Is rover ``v`` down within :data:`DECK_RADIUS` of the carrier (None: not known)?"""
    if v.position is None or carrier.position is None or v.on_ground is None:
        return None
    lat, lon, alt = v.position
    e, n, _u = geodetic_to_enu(lat, lon, alt, Origin(*carrier.position))
    return bool(v.on_ground and (e * e + n * n) ** 0.5 <= DECK_RADIUS)


def status_rows(mission: Mission, fleet: Fleet, rows: dict[str, PreflightRow]) -> list[dict[str, str]]:
    """One dict of display cells per vehicle (keys of :data:`COLUMNS`)."""
    out = []
    for vid, v in fleet.vehicles.items():
        pre = rows[vid]
        row = {"id": vid, "role": pre.role, "sysid": str(v.sysid), "url": fleet.urls[vid],
               "link": "-", "autopilot": "-", "armed": "-", "mode": "-", "battery": "-", "position": "-",
               "deck": "-", "gps": "-", "link_loss": "-", "ready": "ready" if pre.ok else "no",
               "reasons": "; ".join(pre.failures)}
        if not v.connected:
            row["link"] = "no answer"
        else:
            row["link"] = "lost" if v.lost else f"ok ({v.last_heard_age or 0.0:.1f} s)"
            row["autopilot"] = v.autopilot.name if v.autopilot else "?"
            row["armed"] = "armed" if v.armed else "disarmed"
            row["mode"] = v.mode_firmware or "?"
            if v.gps_fix_type is not None:
                fix = "3D" if v.gps_fix_type >= 3 else ("no fix" if v.gps_fix_type <= 1 else "2D")
                row["gps"] = f"{fix}, {v.gps_satellites} sat" if v.gps_satellites is not None else fix
            if pre.link_loss:
                row["link_loss"] = pre.link_loss.removeprefix("link loss: ")
            if v.battery_pct is not None:
                row["battery"] = f"{v.battery_pct:.0f} %"
                if pre.range is not None and pre.range < mission.rovers.deploy_range:
                    row["battery"] += f" ({pre.range:.0f} m range)"
            if v.position is not None:
                enu = v.enu
                lat, lon, alt = v.position
                row["position"] = (f"{enu[0]:.1f}, {enu[1]:.1f}, {enu[2]:.1f}" if enu else
                                   f"{lat:.7f}, {lon:.7f}, {alt:.1f}")
            if pre.role == "rover":
                deck = on_deck(v, fleet.carrier)
                row["deck"] = "?" if deck is None else ("on deck" if deck else "off deck")
        out.append(row)
    return out


def json_objects(mission: Mission, fleet: Fleet, rows: dict[str, PreflightRow]) -> list[dict[str, Any]]:
    """One object per vehicle: identity, link, telemetry, every check and the verdict."""
    out = []
    for vid, v in fleet.vehicles.items():
        pre = rows[vid]
        enu = v.enu if v.connected else None
        deck = on_deck(v, fleet.carrier) if v.connected and pre.role == "rover" else None
        out.append({
            "vehicle": vid, "role": pre.role, "sysid": v.sysid, "url": fleet.urls[vid],
            "connected": v.connected, "lost": bool(v.connected and v.lost),
            "ready": pre.ok, "reasons": pre.failures,
            "checks": [{"name": c.name, "ok": c.ok, "detail": c.detail} for c in pre.checks],
            "autopilot": v.autopilot.name if v.connected and v.autopilot else None,
            "armed": v.armed if v.connected else None,
            "mode": v.mode_firmware if v.connected else None,
            "system_status": v.system_status if v.connected else None,
            "battery_pct": v.battery_pct if v.connected else None,
            "range_m": None if pre.range is None else round(pre.range, 1),
            "deploy_range_m": mission.rovers.deploy_range if pre.role == "rover" else None,
            "gps_fix_type": v.gps_fix_type if v.connected else None,
            "satellites": v.gps_satellites if v.connected else None,
            "position": list(v.position) if v.connected and v.position is not None else None,
            "enu": [round(x, 2) for x in enu] if enu else None,
            "on_deck": deck,
            "link_loss": pre.link_loss.removeprefix("link loss: ") if pre.link_loss else None,
            "warnings": pre.warnings,
        })
    return out


def plain_lines(cells: list[dict[str, str]]) -> list[str]:
    """A header and one line per vehicle, cells separated by tabs, none cut."""
    lines = ["\t".join(title for _, title in COLUMNS)]
    lines += ["\t".join(row[key] or "-" for key, _ in COLUMNS) for row in cells]
    return lines


def print_table(mission: Mission, cells: list[dict[str, str]], out: IO[str] | None = None) -> None:
    """The table on a terminal (:func:`plain_lines` without one)."""
    out = out or sys.stdout
    if not out.isatty():
        for line in plain_lines(cells):
            print(line, file=out)
        return
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"Preflight of {mission.name}", title_justify="left")
    for key, title in COLUMNS:
        table.add_column(title, no_wrap=key != "reasons")
    for row in cells:
        table.add_row(*(row[k] for k, _ in COLUMNS), style=None if row["ready"] == "ready" else "red")
    Console(file=out).print(table)


def not_ready_report(fleet: Fleet, rows: dict[str, PreflightRow]) -> list[str]:
    """Lines for stderr when a vehicle is not ready: a header naming each vehicle's first failing
    check (the real reason), one line per vehicle with every reason, and the connection hint only
    when a vehicle did not answer."""
    failing = [vid for vid, pre in rows.items() if not pre.ok]
    if not failing:
        return []
    first = ", ".join(f"{vid} {next(c.name for c in rows[vid].checks if not c.ok)}" for vid in failing)
    lines = [f"fleetctl: {len(failing)} vehicle(s) not ready ({first}):"]
    for vid in failing:
        v = fleet.vehicles[vid]
        if not v.connected:
            lines.append(f"  {fleet.failure_line(vid)}")
        else:
            lines.append(f"  {vid} (sysid {v.sysid}) at {fleet.urls[vid]}: " + "; ".join(rows[vid].failures))
    if any(not fleet.vehicles[vid].connected or fleet.vehicles[vid].lost for vid in failing):
        lines.append(f"  no heartbeat: {CONNECT_HINT}")
    return lines


def print_json(objects: list[dict[str, Any]], out: IO[str] | None = None) -> None:
    out = out or sys.stdout
    for obj in objects:
        print(json.dumps(obj, sort_keys=False), file=out)


__all__ = ["COLUMNS", "DECK_RADIUS", "json_objects", "not_ready_report", "on_deck", "plain_lines",
           "print_json", "print_table", "status_rows"]
