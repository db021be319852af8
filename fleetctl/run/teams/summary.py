"""The summary of a run of several teams (``RUN/summary.json``, schema ``fleetctl.summary/1``):
the one-team keys over the whole mission (a task is reached when the team owning it reached it;
the makespan is the latest team's) plus ``teams`` (one entry per carrier) and ``handovers``
(docs/summary-json.md, docs/teams.md)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from fleetctl.run.summary import SUMMARY_SCHEMA

if TYPE_CHECKING:
    from fleetctl.run.teams.coordinator import TeamsFlight
    from fleetctl.run.teams.team_run import TeamRun


def teams_summary(tr: TeamsFlight) -> dict[str, Any]:
    m, board, cmd = tr.mission, tr.board, tr.command
    deploys, collects = tr.runs.get("deploy", {}), tr.runs.get("collect", {})
    order = [t.id for t in m.tasks]
    reached = [t for t in order if t in board.reached] if cmd != "collect" else []
    unserved = [t for t in order if t not in board.reached] if cmd != "collect" else []
    now = [r for run in collects.values() for r in run.loaded_at]
    loaded = list(dict.fromkeys([*tr.loaded_before, *now]))
    unreachable = dict(tr.left) | {
        r: f"{cid}: out of reach (its range left)"
        for cid, run in collects.items()
        if "collect" in run.results
        for r in run.results["collect"].rovers_unreachable
    }
    summaries = {phase: {cid: o.summary for cid, o in outs.items()} for phase, outs in tr.outcomes.items()}
    deploy_ok = cmd == "collect" or ((bool(deploys) or tr.deployed_before) and not unserved)
    # as one team counts it: every rover loaded but those out of reach (and those lost before it began)
    collect_ok = cmd == "deploy" or all(
        "collect" in r.results and r.results["collect"].complete for r in collects.values()
    )
    complete = not tr.interrupted and tr.error is None and deploy_ok and collect_ok
    dep_plan, col_plan = tr.plans.get("deploy"), tr.plans.get("collect")
    # the mission's makespan is the latest team's (each from its own carrier's start)
    dep_flown = _latest([_deploy_flown(tr, cid, r) for cid, r in deploys.items()])
    col_flown = _latest([_collect_flown(r) for r in collects.values()])
    dep_planned = _latest([r.deploy_rounds.first_planned for r in deploys.values()])
    col_planned = _latest([_planned(r, "collect") for r in collects.values()])
    planned, flown = _makespans(tr, dep_planned, col_planned, dep_flown, col_flown)
    allocated, _ = _makespans(
        tr, dep_plan.makespan if dep_plan else None, col_plan.makespan if col_plan else None, None, None
    )
    airborne: dict[str, Any] = {}
    lost: list[str] = []
    for outs in summaries.values():
        for s in outs.values():
            airborne.update(s.get("rovers_airborne") or {})
            lost += [r for r in s.get("rovers_lost", []) if r not in lost and r not in loaded]
    for r in loaded:
        airborne.pop(r, None)
    out: dict[str, Any] = {
        "schema": SUMMARY_SCHEMA,
        "mission": m.name,
        "phase": cmd,
        "result": "complete" if complete else ("interrupted" if tr.interrupted else "incomplete"),
        "tasks_reached": reached,
        "tasks_done": list(reached) if cmd == "run" and complete else [],  # the dwell was their work
        "tasks_unserved": unserved,
        "tasks_unserved_reasons": {t: _reason(tr, t) for t in unserved},
        "rovers_loaded": loaded,
        "rovers_lost": lost,
        "rovers_airborne": airborne,
        "rovers_unreachable": unreachable,
        "makespan_planned": _round(planned),
        "makespan_allocated": _round(allocated),
        "makespan_flown": _round(flown),
        "replans": sum(int(s.get("replans", 0)) for outs in summaries.values() for s in outs.values()),
        "teams": [_team(tr, cid, deploys.get(cid), collects.get(cid)) for cid in board.teams],
        "handovers": [
            {"tasks": h.tasks, "from": h.from_team, "to": h.to_team, "why": h.why, "T": round(h.t - tr.t0, 3)}
            for h in board.handovers
        ],
        "journal": str(tr.journal.path),
    }
    if cmd == "run":
        out["phases"] = {
            "deploy": {"planned": dep_planned, "flown": dep_flown},
            "dwell": {"planned": tr.dwell_planned, "flown": tr.dwell_flown},
            "collect": {"planned": col_planned, "flown": col_flown},
        }
    if tr.error is not None:
        out["error"] = tr.error
    return out


def _team(tr: TeamsFlight, cid: str, dep: TeamRun | None, col: TeamRun | None) -> dict[str, Any]:
    e, board = tr.board.teams[cid], tr.board
    dep_plan, col_plan = tr.plans.get("deploy"), tr.plans.get("collect")
    out: dict[str, Any] = {"carrier": cid, "status": e.status, "lost": e.lost, "rovers": list(e.rovers)}
    if dep is not None:
        mine = [t for t, (team, _) in board.reached.items() if team == cid]
        out["deploy"] = {
            "tasks_planned": e.tasks,
            "tasks_received": [t.id for t in e.received],
            "tasks_reached": mine,
            "rounds": dep.deploy_rounds.flown,
            "makespan_planned": _round(dep.deploy_rounds.first_planned),
            "makespan_allocated": _round(dep_plan.team(cid).makespan) if dep_plan else None,
            "makespan_flown": _round(_deploy_flown(tr, cid, dep)),
            "result": tr.outcomes.get("deploy", {}).get(cid).summary["result"]  # type: ignore[union-attr]
            if cid in tr.outcomes.get("deploy", {})
            else None,
            "records": str(dep.journal.dir),
        }
    elif tr.deployed_before:  # resumed after the deployment: what its records told
        out["deploy"] = {
            "tasks_planned": e.tasks,
            "tasks_received": [t.id for t in e.received],
            "tasks_reached": [t for t, (team, _) in board.reached.items() if team == cid],
            "records": str(tr.journal.dir / "teams" / cid / "deploy"),
        }
    if col is not None:
        out["collect"] = {
            "rovers_planned": list(col.mission.rovers.ids),
            "rovers_loaded": list(col.loaded_at),
            "makespan_planned": _round(_planned(col, "collect")),
            "makespan_allocated": _round(col_plan.team(cid).makespan) if col_plan else None,
            "makespan_flown": _round(_collect_flown(col)),
            "records": str(col.journal.dir),
        }
    return out


def _latest(spans: list[float | None]) -> float | None:
    given = [x for x in spans if x is not None]
    return max(given) if given else None


def _planned(run: TeamRun, phase: str) -> float | None:
    r = run.results.get(phase)
    return None if r is None else r.planned


def _deploy_flown(tr: TeamsFlight, cid: str, run: TeamRun) -> float | None:
    """From the team's carrier's start to the last task it reached (handed-over ones included)."""
    return _span([run.started_at], [t for team, t in tr.board.reached.values() if team == cid])


def _collect_flown(run: TeamRun) -> float | None:
    return (
        None
        if run.collect_ended is None or run.collect_started is None
        else (run.collect_ended - run.collect_started)
    )


def _span(starts: list[float | None], ends: list[float]) -> float | None:
    """From the first start to the last end (mission clock), None before anything happened."""
    s = [t for t in starts if t is not None]
    return max(ends) - min(s) if s and ends else (0.0 if s else None)


def _makespans(
    tr: TeamsFlight,
    dep_planned: float | None,
    col_planned: float | None,
    dep_flown: float | None,
    col_flown: float | None,
) -> tuple[float | None, float | None]:
    if tr.command == "deploy":
        return dep_planned, dep_flown
    if tr.command == "collect":
        return col_planned, col_flown
    dwell = tr.dwell_planned if tr.dwell_planned is not None else tr.mission.dwell
    planned = None if dep_planned is None or col_planned is None else dep_planned + dwell + col_planned
    flown = (
        None if dep_flown is None or col_flown is None else dep_flown + (tr.dwell_flown or 0.0) + col_flown
    )
    return planned, flown


def _reason(tr: TeamsFlight, task: str) -> str:
    owner = tr.board.owner.get(task)
    s = tr.outcomes.get("deploy", {}).get(owner or "")
    why = (s.summary.get("tasks_unserved_reasons") or {}).get(task) if s is not None else None
    return f"{owner}: {why or 'not reached'}"


def _round(x: float | None) -> float | None:
    return None if x is None else round(x, 3)


__all__ = ["teams_summary"]
