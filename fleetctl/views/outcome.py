"""The lines a flying command ends with (docs/cli.md): what the run achieved, from its summary
(docs/summary-json.md), and a line per team of a run of several carriers."""

from __future__ import annotations

from typing import Any

from fleetctl.mission import Mission
from fleetctl.run.lifecycle import RunOutcome


def outcome_lines(command: str, mission: Mission, outcome: RunOutcome) -> list[str]:
    """``deploy complete: 8/8 tasks reached, makespan 41.2 s (planned 40.9 s); records in DIR``,
    then ``  team ...`` for each team."""
    s = outcome.summary
    n_tasks = len(s.get("tasks_reached", [])) + len(s.get("tasks_unserved", []))
    first = (f"{command} {s['result']}: "
             + (f"{len(s['tasks_reached'])}/{n_tasks or len(mission.tasks)} tasks reached"
                if command != "collect" else f"{len(s['rovers_loaded'])} rovers loaded")
             + (f", {len(s['rovers_airborne'])} rovers airborne" if s.get("rovers_airborne") else "")
             + (f", makespan {s['makespan_flown']:.1f} s (planned {s['makespan_planned']:.1f} s)"
                if s.get("makespan_flown") is not None and s.get("makespan_planned") is not None else "")
             + f"; records in {outcome.run_dir}")
    return [first] + ["  " + team_line(team) for team in s.get("teams", [])]


def team_line(team: dict[str, Any]) -> str:
    """One team's part of a run of several carriers (the summary's ``teams`` entry)."""
    parts = [f"team {team['carrier']}" + (" (carrier lost)" if team.get("lost") else "")]
    for phase in ("deploy", "collect"):
        p = team.get(phase)
        if p is not None:
            parts.append(f"{phase}: {_phase_part(phase, p)}")
    return "; ".join(parts)


def _phase_part(phase: str, p: dict[str, Any]) -> str:
    if phase == "deploy":
        got = f"{len(p['tasks_reached'])}/{len(p['tasks_planned']) + len(p['tasks_received'])} tasks reached"
        if p["tasks_received"]:
            got += f" ({len(p['tasks_received'])} handed to it)"
    else:
        got = f"{len(p['rovers_loaded'])}/{len(p['rovers_planned'])} rovers loaded"
    if p.get("makespan_flown") is not None and p.get("makespan_planned") is not None:
        got += f" in {p['makespan_flown']:.1f} s (planned {p['makespan_planned']:.1f} s)"
    return got
