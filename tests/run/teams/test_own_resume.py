"""Which run folders ``fleetctl resume`` takes for a ``--team ID`` controller's
(fleetctl.run.teams.own_resume): the ones whose ``run`` record names a team; any other folder is
left to the one-team and every-team resumptions, and an unreadable journal is refused. (Flying a
team's run again: tests/run/test_resume_teams.py.)"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fleetctl.run.resume import ResumeError
from fleetctl.run.teams.own_resume import is_own_team_run, own_team_resumption


def _journal(d: Path, *records: dict[str, object]) -> Path:
    d.mkdir(parents=True, exist_ok=True)
    (d / "journal.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records), encoding="utf-8")
    return d


def test_a_folder_without_a_journal_is_not_a_team_run(tmp_path: Path) -> None:
    assert not is_own_team_run(tmp_path)
    assert own_team_resumption(tmp_path, None, None, None) is None


def test_a_run_record_without_a_team_is_not_a_team_run(tmp_path: Path) -> None:
    d = _journal(tmp_path / "run", {"t": 0.0, "kind": "run", "command": "deploy", "mission": "m"},
                 {"t": 1.0, "kind": "phase", "phase": "deploy"})
    assert not is_own_team_run(d)
    assert own_team_resumption(d, None, "lee", 5.0) is None


def test_a_run_record_naming_a_team_is_one(tmp_path: Path) -> None:
    d = _journal(tmp_path / "run", {"t": 0.0, "kind": "run", "command": "deploy", "team": "c1"})
    assert is_own_team_run(d)


def test_a_journal_that_cannot_be_read_is_refused(tmp_path: Path) -> None:
    d = tmp_path / "run"
    d.mkdir()
    (d / "journal.jsonl").write_text('not json\n{"kind": "run", "team": "c1"}\n', encoding="utf-8")
    with pytest.raises(ResumeError, match="not a journal record"):
        own_team_resumption(d, None, None, None)
