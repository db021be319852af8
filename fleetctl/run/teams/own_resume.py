"""``fleetctl resume`` of a ``--team ID`` controller's run folder (docs/teams.md#resume): its
``run`` record names the team; the run goes on over the team's share (the allocation every team's
controller computes alike) or, for ``collect --team``, its deck."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from fleetctl.journal import JOURNAL_NAME
from fleetctl.mission import Mission, MissionError
from fleetctl.mission.teams import team_mission
from fleetctl.run.resume import ResumeError, Resumption, read_records, read_run, resumption_of
from fleetctl.run.teams.own_controller import team_shares
from planners import PlanningError


@dataclass(frozen=True)
class OwnTeamResumption:
    """What a team's controller resumes: the whole mission, the team, the team's interrupted run,
    and the planner and dwell to go on with (given again, else the interrupted run's)."""

    mission: Mission
    team: str
    resumption: Resumption
    planner: str | None
    dwell: float | None


def is_own_team_run(run_dir: str | Path) -> bool:
    """Was ``run_dir`` flown by a ``--team ID`` controller (its ``run`` record names a team)?"""
    path = Path(run_dir) / JOURNAL_NAME
    if not path.is_file():
        return False
    run = next((r for r in read_records(path) if r["kind"] == "run"), None)
    return run is not None and isinstance(run.get("team"), str)


def own_team_resumption(run_dir: str | Path, mission_file: str | Path | None, planner: str | None,
                        dwell: float | None) -> OwnTeamResumption | None:
    """The resumption of a ``--team ID`` controller's run folder (None for any other run folder);
    :class:`ResumeError` when it cannot be resumed."""
    if not is_own_team_run(run_dir):
        return None
    d, records, run, whole = read_run(run_dir, mission_file)
    team, command = str(run["team"]), str(run["command"])
    planner = planner if planner is not None else run.get("planner")
    dwell = dwell if dwell is not None else run.get("dwell")
    try:
        tasks = () if command == "collect" else team_shares(whole, planner).get(team, [])
        own = team_mission(whole, team, tasks=tasks)
    except (MissionError, KeyError, PlanningError) as e:
        raise ResumeError(f"{d}: cannot fly team {team} of {whole.path or whole.name} again: {e}") from None
    resumption = resumption_of(d, records, command, own, float(run.get("speedup") or 1.0),
                               {"planner": run.get("planner"), "dwell": run.get("dwell")})
    return OwnTeamResumption(whole, team, resumption, planner, dwell)
