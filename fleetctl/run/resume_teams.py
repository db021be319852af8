"""``fleetctl resume --run DIR`` of a run of several teams (docs/teams.md#resume).

A run of several teams (:class:`~fleetctl.run.teams.coordinator.TeamsFlight`) keeps two kinds of
records: the run's journal ``RUN/journal.jsonl`` (the ``run`` record naming the teams, the
``teams_plan`` records of how the work was shared, each team's run ``started`` and ``ended``, the
``handover`` records, the ``dwell``) and one journal per team and phase,
``RUN/teams/<carrier>/<phase>/journal.jsonl``, the journal of an ordinary one-team run.

:func:`load_teams_resumption` reads them into a :class:`TeamsResumption`:

* the phase interrupted: ``deploy`` until the ``dwell`` record, ``dwell`` until the collection
  was shared (or a team's collection started), then ``collect``;
* who owns each task: the deployment's shares, then every recorded hand-over (a task handed to
  another team is that team's; the team that gave it up is never handed it again); the teams
  whose carrier was lost (``carrier_lost``) stay lost: they are handed nothing;
* for each team whose deployment journal exists, a :class:`~fleetctl.run.resume.Resumption` of
  that journal over the tasks the team owns now: the tasks its rovers reached, the rovers it
  launched and where to, refused or unusable rovers. The resumed run flies each team's
  deployment on from there (reconciled against the live fleet by the team's run, as one team's
  resume is);
* the teams whose deployment run had ended (a carrier that failed its preflight, a team whose work
  was over): they are not flown again, what they reached counts and their run's summary stands;
* the dwell's start (what is left of it is dwelt), and for the collection the rovers every
  team launched (the collection is shared again from the live fleet: rovers already on a deck
  are not collected again) and those already loaded.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fleetctl.journal import JOURNAL_NAME
from fleetctl.mission import Mission
from fleetctl.mission.teams import mission_teams, several_teams, team_mission
from fleetctl.run.kinds import Ev, phases_of
from fleetctl.run.resume import ResumeError, Resumption, read_records, read_run, resumption_of

TEAMS_FOLDER = "teams"  # RUN/teams/<carrier>/<phase>/: each team's records


@dataclass
class Handed:
    """A hand-over recorded in the run's journal."""

    tasks: list[str]
    from_team: str
    to_team: str | None
    why: str
    t: float  # unix time of its record


@dataclass
class TeamsResumption:
    """An interrupted run of several teams, as its journals tell it (see the module docstring)."""

    run_dir: Path
    command: str  # deploy | collect | run
    mission: Mission  # the whole mission (every team)
    phase: str  # the phase of the run that was interrupted
    scale: float  # mission seconds per wall second of the interrupted run
    options: dict[str, Any] = field(default_factory=dict)  # planner, dwell of the interrupted run
    shares: dict[str, list[str]] | None = None  # team -> its tasks of the deployment (None: not shared)
    handovers: list[Handed] = field(default_factory=list)
    deploy: dict[str, Resumption] = field(default_factory=dict)  # team -> its deployment's journal
    collect: dict[str, Resumption] = field(default_factory=dict)  # team -> its collection's journal
    dwell_started: float | None = None  # unix time
    lost: list[str] = field(default_factory=list)  # teams whose carrier was lost (they take no more tasks)
    deploy_ended: dict[str, str] = field(default_factory=dict)  # team -> its deployment run's result, if over

    # -- who owns what ---------------------------------------------------------------------------
    def owner(self) -> dict[str, str]:
        """task -> the team that owns it now (the shares, then every hand-over with a receiver)."""
        own = {t: cid for cid, tasks in (self.shares or {}).items() for t in tasks}
        for h in self.handovers:
            if h.to_team is not None:
                own.update({t: h.to_team for t in h.tasks})
        return own

    def team_tasks(self, team: str) -> list[str]:
        """The tasks ``team`` owns now, in the mission's order."""
        own = self.owner()
        return [t.id for t in self.mission.tasks if own.get(t.id) == team]

    def gave_up(self) -> dict[str, set[str]]:
        """task -> the teams that handed it over (it never goes back to them)."""
        out: dict[str, set[str]] = {}
        for h in self.handovers:
            for t in h.tasks:
                out.setdefault(t, set()).add(h.from_team)
        return out

    def team_deploy(self, team: str) -> Resumption | None:
        """The resumption of ``team``'s deployment (None: its run had not begun its records)."""
        return self.deploy.get(team)

    # -- what the teams did ----------------------------------------------------------------------
    def reached(self) -> dict[str, tuple[str, float]]:
        """task -> (the team whose rover reached it, s into its deployment), of the tasks each
        team owns now."""
        own = self.owner()
        out: dict[str, tuple[str, float]] = {}
        for cid, res in self.deploy.items():
            for tid, flown in res.board.reached().items():
                if own.get(tid, cid) == cid:
                    out.setdefault(tid, (cid, flown))
        return out

    def launched(self) -> list[str]:
        """Every rover a team's deployment launched (the collection brings them back), sorted."""
        return sorted({r for res in self.deploy.values() for r in res.board.launched})

    def loaded(self) -> list[str]:
        """Rovers a team's collection had loaded before the run stopped, sorted."""
        return sorted({r for res in self.collect.values() for r in res.loaded})

    # -- for the run ---------------------------------------------------------------------------------
    def phases_left(self) -> list[str]:
        order = phases_of(self.command)
        return order[order.index(self.phase):] if self.phase in order else order

    def dwell_left(self, wait: float) -> float:
        if self.phase != "dwell" or self.dwell_started is None:
            return wait
        return max(0.0, wait - (time.time() - self.dwell_started) * self.scale)

    def deploy_summary(self, team: str) -> dict[str, Any]:
        """The summary a team's ended deployment run wrote (its folder's ``summary.json``), or its
        result alone when that file is missing or unreadable."""
        path = team_folder(self.run_dir, team, "deploy") / "summary.json"
        try:
            summary = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            summary = None
        if not isinstance(summary, dict):
            summary = {"result": self.deploy_ended.get(team, "incomplete")}
        return summary

    def record(self) -> dict[str, Any]:
        """The run journal's ``resumed`` record: what the journals told."""
        return {
            "command": self.command,
            "phase": self.phase,
            "shares": self.shares,
            "owner": self.owner(),
            "handovers": [{"tasks": h.tasks, "from": h.from_team, "to": h.to_team} for h in self.handovers],
            "reached": sorted(self.reached()),
            "launched": self.launched(),
            "loaded": self.loaded(),
            "teams_resumed": sorted(self.deploy) if self.phase == "deploy" else sorted(self.collect),
            "lost": self.lost,
            "deploy_ended": self.deploy_ended,
        }


def team_folder(run_dir: Path, team: str, phase: str) -> Path:
    return run_dir / TEAMS_FOLDER / team / phase


def is_teams_run(run_dir: str | Path) -> bool:
    """Whether ``run_dir`` holds the records of a run of several teams (its ``run`` record names
    the teams); False when there is no readable journal (the one-team loader says why)."""
    path = Path(run_dir) / JOURNAL_NAME
    if not path.is_file():
        return False
    try:
        records = read_records(path)
    except ResumeError:
        return False
    run = next((r for r in records if r["kind"] == Ev.RUN), None)
    return run is not None and isinstance(run.get("teams"), dict)


def load_teams_resumption(run_dir: str | Path, mission_file: str | Path | None = None) -> TeamsResumption:
    """Read the folder of a run of several teams (see the module docstring); :class:`ResumeError`
    when it cannot be resumed."""
    d, records, run, mission = read_run(run_dir, mission_file)
    if not several_teams(mission):
        raise ResumeError(f"{d}: the journal is of a run of several teams and the mission has one carrier; "
                          "the journal and the mission do not match")
    teams = {t.carrier.id for t in mission_teams(mission)}
    named = set(run.get("teams") or {})
    if named != teams:
        raise ResumeError(f"{d / JOURNAL_NAME}: the journal's teams {sorted(named)} are not the mission's "
                          f"carriers {sorted(teams)}; the journal and the mission do not match")
    command = str(run["command"])
    res = TeamsResumption(d, command, mission, "collect" if command == "collect" else "deploy",
                          float(run.get("speedup") or 1.0),
                          options={"planner": run.get("planner"), "dwell": run.get("dwell")})
    _replay(res, records)
    if res.command != "collect":
        for cid in teams:
            path = team_folder(d, cid, "deploy") / JOURNAL_NAME
            if path.is_file():
                own = team_mission(mission, cid, tasks=res.team_tasks(cid))
                recs = read_records(path)
                res.deploy[cid] = resumption_of(path.parent, recs, "deploy", own, _scale(recs, res.scale),
                                                res.options)
    for cid in teams:
        path = team_folder(d, cid, "collect") / JOURNAL_NAME
        if path.is_file():
            recs = read_records(path)
            own = team_mission(mission, cid, tasks=())
            res.collect[cid] = resumption_of(path.parent, recs, "collect", own, _scale(recs, res.scale),
                                             res.options)
    return res


def _scale(records: list[dict[str, Any]], default: float) -> float:
    run = next((r for r in records if r["kind"] == Ev.RUN), None)
    return float(run.get("speedup") or default) if run is not None else default


def _replay(res: TeamsResumption, records: list[dict[str, Any]]) -> None:
    """The run journal's records, in order: the shares, the hand-overs, the phase reached."""
    for r in records:
        kind = r["kind"]
        if kind == Ev.TEAMS_PLAN and r.get("phase") == "deploy" and res.shares is None:
            shares = r.get("shares") or {}
            res.shares = {str(c): [str(t) for t in ts if t is not None] for c, ts in shares.items()}
        elif kind == Ev.TEAMS_PLAN and r.get("phase") == "collect":
            res.phase = "collect"
        elif kind == Ev.HANDOVER and isinstance(r.get("tasks"), list) and \
                isinstance(r.get("from_team"), str):
            to = r.get("to_team")
            res.handovers.append(Handed([str(t) for t in r["tasks"]], r["from_team"],
                                        to if isinstance(to, str) else None, str(r.get("why") or ""),
                                        float(r["t"])))
        elif kind == Ev.CARRIER_LOST and isinstance(r.get("vehicle"), str) and r["vehicle"] not in res.lost:
            res.lost.append(r["vehicle"])
        elif kind == Ev.DWELL and res.phase == "deploy" and res.command == "run":
            res.phase = "dwell"
            res.dwell_started = float(r["t"])
        elif kind == Ev.TEAM and r.get("phase") == "deploy" and r.get("status") == "ended" and \
                isinstance(r.get("team"), str):
            res.deploy_ended[r["team"]] = str(r.get("result") or "incomplete")
        elif (kind == Ev.TEAM and r.get("phase") == "collect") or kind == Ev.NOTHING_TO_COLLECT:
            res.phase = "collect"


__all__ = ["TeamsResumption", "is_teams_run", "load_teams_resumption", "team_folder"]
