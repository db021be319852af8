"""What ``fleetctl resume`` reads from the records of a run of several teams
(:mod:`fleetctl.run.resume_teams`): the shares, the hand-overs already recorded (a task handed to
another team is that team's, and never goes back to the team that gave it up), each team's own
journal (tasks reached, rovers launched), and the phase the run was in. No fleet flies here:
the run folders are written as a killed controller leaves them."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

from fleetctl.run.crew import Crew
from fleetctl.run.lifecycle import RunOptions
from fleetctl.run.resume import ResumeError
from fleetctl.run.resume_teams import is_teams_run, load_teams_resumption
from fleetctl.run.teams.coordinator import TeamsFlight
from tests.run.teams.teams_helpers import two_teams

TEAMS = {"c1": ["r1", "r2"], "c2": ["r3", "r4"]}


def _mission(_tmp_path: Path) -> dict[str, Any]:
    d = two_teams()
    for c in d["carriers"]:
        c["connection"] = "udp://127.0.0.1:14999"
    return d


def _write(path: Path, records: list[dict[str, Any]]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    t = time.time() - 60.0
    lines = [json.dumps({"t": t + k, "elapsed": float(k), **r}) for k, r in enumerate(records)]
    path.write_text("".join(line + "\n" for line in lines), encoding="utf-8")


def _folder(tmp_path: Path, d: dict[str, Any], command: str, run: list[dict[str, Any]],
            teams: dict[str, list[dict[str, Any]]] | None = None) -> Path:
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / "mission.yaml").write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
    head = {"kind": "run", "mission": d["name"], "command": command, "file": "", "sim": False, "speedup": 1.0,
            "planner": None, "dwell": None, "teams": TEAMS}
    _write(run_dir / "journal.jsonl", [head, *run])
    for where, records in (teams or {}).items():
        team_head = {"kind": "run", "mission": d["name"], "command": where.split("/")[1], "file": "",
                     "sim": False, "speedup": 1.0}
        _write(run_dir / "teams" / where / "journal.jsonl", [team_head, *records])
    return run_dir


SHARES = {"kind": "teams_plan", "phase": "deploy", "makespan": 10.0, "allocation": "search",
          "shares": {"c1": ["t1", "t2"], "c2": ["t3", "t4"]}}
HANDOVER = {"kind": "handover", "tasks": ["t4"], "from_team": "c2", "to_team": "c1",
            "why": "c2 could not serve them (t4: rover refused)"}
C2_DEPLOY = [{"kind": "phase", "phase": "deploy"},
             {"kind": "carrier_started", "vehicle": "c2"},
             {"kind": "launch", "vehicle": "r3", "task": "t3", "stop": 1},
             {"kind": "rover_launched", "vehicle": "r3", "task": "t3"},
             {"kind": "task_reached", "vehicle": "r3", "task": "t3", "flown": 4.0},
             {"kind": "rover_refused", "vehicle": "r4"},
             {"kind": "task_unserved", "task": "t4", "text": "no spare rover left on the deck"}]
C1_DEPLOY = [{"kind": "phase", "phase": "deploy"},
             {"kind": "carrier_started", "vehicle": "c1"},
             {"kind": "launch", "vehicle": "r1", "task": "t1", "stop": 1},
             {"kind": "rover_launched", "vehicle": "r1", "task": "t1"},
             {"kind": "launch", "vehicle": "r2", "task": "t2", "stop": 2}]


def test_a_recorded_handover_is_honoured(tmp_path: Path) -> None:
    run_dir = _folder(tmp_path, _mission(tmp_path), "deploy", [SHARES, HANDOVER],
                      {"c1/deploy": C1_DEPLOY, "c2/deploy": C2_DEPLOY})
    assert is_teams_run(run_dir)
    res = load_teams_resumption(run_dir)
    assert res.phase == "deploy"
    assert res.owner() == {"t1": "c1", "t2": "c1", "t3": "c2", "t4": "c1"}
    assert res.team_tasks("c1") == ["t1", "t2", "t4"]
    assert res.team_tasks("c2") == ["t3"]
    assert res.gave_up() == {"t4": {"c2"}}
    c1, c2 = res.deploy["c1"], res.deploy["c2"]
    # c1 flies the handed task; its own journal: r1 flies to t1, r2's launch was cut short
    assert sorted(c1.board.entries) == ["t1", "t2", "t4"]
    assert c1.board.flying() == {"t1": "r1"}
    assert c1.intents == {"r2": "t2"}
    assert [t.id for t in c1.board.pooled()] == ["t2", "t4"]
    # c2 no longer owns t4; what it reached counts
    assert sorted(c2.board.entries) == ["t3"]
    assert res.reached() == {"t3": ("c2", 4.0)}
    assert res.launched() == ["r1", "r3"]
    # the run of every team takes the records over: owners, who gave what up, what was handed to whom
    tr = Crew(res.mission, "deploy", RunOptions(teams_resume=res), TeamsFlight).flight
    tr._resumed_records(res)
    assert tr.board.owner == res.owner()
    assert tr.board.gave_up == {"t4": {"c2"}}
    assert [t.id for t in tr.board.teams["c1"].received] == ["t4"]
    assert [(h.tasks, h.from_team, h.to_team) for h in tr.board.handovers] == [(["t4"], "c2", "c1")]
    assert tr.board.handovers[0].t <= tr.t0  # recorded before the resumed run began


@pytest.mark.parametrize(("command", "records", "phase"), [
    ("run", [SHARES], "deploy"),
    ("run", [SHARES, {"kind": "dwell", "text": "every team dwells 2 s on task"}], "dwell"),
    ("run", [SHARES, {"kind": "dwell"}, {"kind": "teams_plan", "phase": "collect", "shares": {}}], "collect"),
    ("run", [SHARES, {"kind": "dwell"}, {"kind": "nothing_to_collect"}], "collect"),
    ("collect", [], "collect"),
    ("deploy", [], "deploy"),
])
def test_the_phase_interrupted(tmp_path: Path, command: str, records: list[dict[str, Any]],
                               phase: str) -> None:
    res = load_teams_resumption(_folder(tmp_path, _mission(tmp_path), command, records))
    assert res.phase == phase
    assert res.phases_left()[0] == phase
    assert res.shares == (SHARES["shares"] if records else None)
    if phase == "dwell":
        assert res.dwell_started is not None
        assert 0.0 <= res.dwell_left(1000.0) < 1000.0  # the time dwelt before the kill is not dwelt again


def test_a_run_of_one_team_is_not_read_as_several(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    _write(run_dir / "journal.jsonl", [{"kind": "run", "command": "deploy"}])
    assert not is_teams_run(run_dir)
    assert not is_teams_run(tmp_path / "nowhere")


def test_a_journal_of_other_teams_is_refused(tmp_path: Path) -> None:
    d = _mission(tmp_path)
    d["carriers"][1]["id"] = "c9"
    with pytest.raises(ResumeError, match="are not the mission's carriers"):
        load_teams_resumption(_folder(tmp_path, d, "deploy", [SHARES]))


def test_a_lost_carrier_stays_lost(tmp_path: Path) -> None:
    """c1's carrier lost (a ``carrier_lost`` record), its tasks handed to c2: resumed, c1 owns
    nothing, never gets them back, and is lost on the resumed run's board (it is handed nothing)."""
    lost = {"kind": "carrier_lost", "vehicle": "c1", "text": "c1: carrier lost for 1 s: handing over t1, t2"}
    handed = {"kind": "handover", "tasks": ["t1", "t2"], "from_team": "c1", "to_team": "c2",
              "why": "c1's carrier lost for more than 1 s"}
    res = load_teams_resumption(_folder(tmp_path, _mission(tmp_path), "deploy", [SHARES, lost, handed]))
    assert res.lost == ["c1"]
    assert res.record()["lost"] == ["c1"]
    assert res.team_tasks("c1") == [] and res.team_tasks("c2") == ["t1", "t2", "t3", "t4"]
    tr = Crew(res.mission, "deploy", RunOptions(teams_resume=res), TeamsFlight).flight
    tr._resumed_records(res)
    assert tr.board.teams["c1"].lost and not tr.board.teams["c1"].can_receive
    assert not tr.board.teams["c2"].lost


@pytest.mark.parametrize(("command", "deployed_before"), [("collect", False), ("run", True)])
def test_a_resumed_collection_has_a_deployment_only_in_a_run(tmp_path: Path, command: str,
                                                             deployed_before: bool) -> None:
    """A ``run`` resumed in its collection deployed before the kill (its summary says what its
    records told); a ``collect`` run never deployed."""
    records = [SHARES, {"kind": "dwell"}] if command == "run" else []
    records.append({"kind": "teams_plan", "phase": "collect", "shares": TEAMS})
    res = load_teams_resumption(_folder(tmp_path, _mission(tmp_path), command, records))
    assert res.phase == "collect"
    tr = Crew(res.mission, command, RunOptions(teams_resume=res), TeamsFlight).flight
    tr._resumed_records(res)
    assert tr.deployed_before is deployed_before


def test_a_team_whose_deployment_was_over_is_not_flown_again(tmp_path: Path) -> None:
    """c1's carrier failed its preflight: its deployment run ended (a ``team`` record, its summary
    written) and its tasks went to c2; the run was killed while c2 flew on. Resumed, c1 stays over:
    handed nothing, its run's summary stands, only c2 is flown again."""
    ended = {"kind": "team", "team": "c1", "phase": "deploy", "status": "ended", "result": "incomplete",
             "error": "c1: preflight: carrier c1: battery 12 % below the 30 % needed"}
    handed = {"kind": "handover", "tasks": ["t1", "t2"], "from_team": "c1", "to_team": "c2",
              "why": "c1: preflight failed"}
    run_dir = _folder(tmp_path, _mission(tmp_path), "deploy", [SHARES, ended, handed],
                      {"c1/deploy": [{"kind": "phase", "phase": "preflight"}], "c2/deploy": C2_DEPLOY})
    c1_summary = {"schema": "fleetctl.summary/1", "result": "incomplete", "error": ended["error"],
                  "tasks_reached": []}
    (run_dir / "teams" / "c1" / "deploy" / "summary.json").write_text(json.dumps(c1_summary))
    res = load_teams_resumption(run_dir)
    assert res.deploy_ended == {"c1": "incomplete"}
    assert res.record()["deploy_ended"] == {"c1": "incomplete"}
    assert res.team_tasks("c1") == [] and res.team_tasks("c2") == ["t1", "t2", "t3", "t4"]
    tr = Crew(res.mission, "deploy", RunOptions(teams_resume=res), TeamsFlight).flight
    tr._resumed_records(res)
    c1 = tr.board.teams["c1"]
    assert c1.finished and c1.status == "done" and not c1.can_receive  # its tasks are c2's now
    assert tr.outcomes["deploy"]["c1"].summary == c1_summary
    assert tr.outcomes["deploy"]["c1"].exit_code == 1
    assert "c2" not in tr.outcomes.get("deploy", {})  # c2 is flown on
