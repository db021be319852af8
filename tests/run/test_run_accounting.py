"""What a run reports: the planned total of `run` uses the dwell actually flown, and commands a
mission cannot fly fail with a message, not a traceback."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from fleetctl.cli import main
from fleetctl.run.flight import execute
from tests.run.ctl_helpers import mission_dict, mission_from

ROOT = Path(__file__).resolve().parents[2]


async def test_run_planned_total_counts_the_dwell_given_not_the_missions(tmp_path: Path) -> None:
    d = mission_dict(rovers=2)
    d["dwell"] = 120.0
    mission = mission_from(d, tmp_path)
    out = await asyncio.wait_for(execute(mission, "run", dwell=3.0, runs_dir=tmp_path / "runs"), 120)
    s = out.summary
    assert out.exit_code == 0, s
    ph = s["phases"]
    assert s["makespan_planned"] == pytest.approx(ph["deploy"]["planned"] + 3.0 + ph["collect"]["planned"],
                                                  abs=1e-3)
    assert s["makespan_flown"] < ph["deploy"]["flown"] + 3.0 + ph["collect"]["flown"] + 5.0


@pytest.mark.parametrize("command", ["deploy", "run"])
def test_deploy_of_a_collection_only_mission_is_a_clear_error(command: str, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    path = ROOT / "missions" / "paper" / "collect_15rovers_d15.yaml"
    code = main([command, "--headless", "--mission", str(path), "--runs", str(tmp_path / "runs")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "no tasks" in err and "fleetctl collect" in err
    assert not (tmp_path / "runs").exists()
