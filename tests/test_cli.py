"""`fleetctl plan` end to end: the summary, the plan JSON contract, the plot, errors."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from fleetctl.cli import main
from fleetctl.mission import load_mission
from tests.plan_checker import check_plan

ROOT = Path(__file__).resolve().parents[1]
DEPLOY_MISSIONS = sorted([ROOT / "missions" / "recon.yaml",
                          *(ROOT / "missions" / "paper").glob("deploy_*.yaml")])


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "fleetctl.cli", *args], capture_output=True, text=True,
                          cwd=ROOT, timeout=120)


@pytest.mark.parametrize("mission", DEPLOY_MISSIONS, ids=lambda p: p.name)
@pytest.mark.parametrize("planner", ["lee", "greedy2opt"])
def test_plan_json_matches_the_contract(mission, planner, capsys):
    assert main(["plan", "--mission", str(mission), "--planner", planner, "--json"]) == 0
    out = capsys.readouterr().out
    plan = json.loads(out)  # nothing but the JSON on stdout
    assert set(plan) == {"schema", "kind", "planner", "carrier", "stops", "makespan", "carrier_distance",
                         "compute_ms", "time_model"}
    assert set(plan["time_model"]) == {"takeoff_time", "land_time", "rover_fixed_time", "vertex_stops",
                                       "takeoff_height"}
    assert plan["schema"] == "fleetctl.plan/1" and plan["kind"] == "deploy" and plan["planner"] == planner
    assert set(plan["carrier"]) == {"start", "heading"}
    for stop in plan["stops"]:
        assert set(stop) == {"position", "arrive", "depart", "carrier_path", "rovers"}
        for r in stop["rovers"]:
            assert set(r) == {"rover", "task", "target", "path", "arrive"}
    m = load_mission(mission)
    c = m.carrier
    check_plan(plan, {"max_speed": c.max_speed, "accel": c.accel, "turn_rate": c.turn_rate,
                      "unload_time": c.unload_time, "load_time": c.load_time,
                      "takeoff_time": m.rovers.takeoff_time, "land_time": m.rovers.land_time,
                      "vertex_stops": True},
               {"max_speed": m.rovers.max_speed, "accel": m.rovers.accel}, m.rovers.deploy_range)
    assert sorted(r["task"] for s in plan["stops"] for r in s["rovers"]) == sorted(t.id for t in m.tasks)


def test_plan_budget_ms_improves_or_keeps_the_quick_plan(capsys):
    recon = str(ROOT / "missions" / "recon.yaml")
    assert main(["plan", "-m", recon, "--json"]) == 0
    quick = json.loads(capsys.readouterr().out)
    assert main(["plan", "-m", recon, "--json", "--budget-ms", "30"]) == 0
    better = json.loads(capsys.readouterr().out)
    assert better["makespan"] <= quick["makespan"] + 1e-6
    with pytest.raises(SystemExit) as exc:
        main(["plan", "-m", recon, "--budget-ms", "-5"])
    assert exc.value.code == 2 and "--budget-ms" in capsys.readouterr().err


def test_summary_and_plot(tmp_path):
    png = tmp_path / "recon.png"
    res = run("plan", "--mission", "missions/recon.yaml", "--plot", str(png))
    assert res.returncode == 0, res.stderr
    for word in ("makespan", "lower bound", "carrier travels", "computed in", "stop"):
        assert word in res.stdout
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000


def test_plot_3d_mission(tmp_path):
    png = tmp_path / "six.png"
    assert main(["plan", "-m", "missions/paper/deploy_6tasks_3d_d7.yaml", "--plot", str(png)]) == 0
    assert png.exists()


def test_direct_refused_with_a_clear_message():
    res = run("plan", "--mission", "missions/paper/deploy_15tasks_d25.yaml", "--planner", "direct")
    assert res.returncode == 2
    assert "Traceback" not in res.stderr and "direct" in res.stderr and "t1" in res.stderr


def test_unknown_planner():
    res = run("plan", "--mission", "missions/recon.yaml", "--planner", "nope")
    assert res.returncode == 2 and "choose one of" in res.stderr and "lee" in res.stderr


def test_bad_mission_file(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text((ROOT / "missions" / "recon.yaml").read_text().replace("max_speed: 1", "max_sped: 1", 1))
    res = run("plan", "--mission", str(bad))
    assert res.returncode == 2
    assert "Traceback" not in res.stderr and "max_sped" in res.stderr and str(bad) in res.stderr


def test_missing_file():
    res = run("plan", "--mission", "missions/nope.yaml")
    assert res.returncode == 2 and "Traceback" not in res.stderr


def test_help_explains():
    res = run("plan", "--help")
    assert res.returncode == 0 and "--planner" in res.stdout and "greedy2opt" in res.stdout


@pytest.mark.parametrize("mission", sorted((ROOT / "missions").glob("**/*.yaml")), ids=lambda p: p.name)
def test_every_mission_file_configures_the_simulated_fleet(mission):
    # What `fleetctl sim` and the embedded fleet of deploy/run start from (every carrier of every team).
    from fleetctl.mission.teams import mission_teams
    from fleetctl.run.sim import sim_fleet_config

    m = load_mission(mission)
    cfg = sim_fleet_config(m)
    teams = mission_teams(m)
    assert [(c.id, c.sysid) for c in cfg.carriers] == [(t.carrier.id, t.carrier.sysid) for t in teams]
    assert [(r.id, r.sysid) for r in cfg.rovers] == [(u.id, u.sysid) for u in m.rovers.units]
