"""Several carriers, planning: allocation properties, the mission keys, ``fleetctl plan``."""

from __future__ import annotations

import copy
import json
import math
import random
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fleetctl.cli import main
from fleetctl.mission import load_mission
from fleetctl.mission.teams import mission_teams, several_teams, teams_problem
from planners import COLLECT_PLANNERS, DEPLOY_PLANNERS, SCREEN_PLANNERS
from planners.core.plan import Plan
from planners.core.problem import CarrierSpec, CollectProblem, CollectRover, DeployProblem, Motion, Task
from planners.core.timing import path_length, retime
from planners.teams import TeamsPlan, TeamsProblem, plan_teams, plan_teams_nearest, teams_lower_bound
from tests.mission.test_mission import BASE, error, load
from tests.plan_checker import check_plan
from tests.planners.test_roadmap import assert_outside

ROOT = Path(__file__).resolve().parents[2]
TWO = ROOT / "missions" / "two_carriers.yaml"
EPS = 1e-6

# ------------------------------------------------------------------------------------ instances


def _carrier(rng: random.Random) -> CarrierSpec:
    return CarrierSpec(max_speed=rng.uniform(8, 16), accel=rng.choice([None, rng.uniform(3, 10)]),
                       turn_rate=rng.choice([None, rng.uniform(1, 4)]), unload_time=rng.uniform(0, 5),
                       load_time=rng.uniform(0, 5), takeoff_time=rng.choice([0.0, 1.5]),
                       land_time=rng.choice([0.0, 2.0]))


def deploy_teams(seed: int, n: int, m: int, spare: int = 2) -> TeamsProblem[DeployProblem]:
    """n tasks in a 200 m square, m carriers with random specs; decks hold n + spare rovers in all,
    split unevenly so that some deck is tight."""
    rng = random.Random(seed)
    tasks = tuple(Task(f"t{i + 1}", (rng.uniform(0, 200), rng.uniform(0, 200),
                                     rng.choice([0.0, rng.uniform(0, 8)]))) for i in range(n))
    total = max(n + spare, m)
    cuts = sorted(rng.sample(range(1, total), m - 1)) if m > 1 else []
    sizes = [b - a for a, b in zip([0, *cuts], [*cuts, total], strict=True)]
    problems, first = [], 0
    for k in range(m):
        deck = tuple(f"r{first + j + 1}" for j in range(sizes[k]))
        first += sizes[k]
        problems.append(DeployProblem(_carrier(rng), Motion(rng.uniform(1, 3)), rng.uniform(15, 35),
                                      (rng.uniform(0, 200), rng.uniform(0, 200), 0.0), rng.uniform(-3, 3),
                                      tasks, deck))
    rover, d = problems[0].rover, problems[0].deploy_range  # one rover type for every team
    return TeamsProblem(tuple(f"c{k + 1}" for k in range(m)),
                        tuple(replace(p, rover=rover, deploy_range=d) for p in problems))


def collect_teams(seed: int, n: int, m: int) -> TeamsProblem[CollectProblem]:
    rng = random.Random(seed)
    rovers = []
    for i in range(n):
        z = rng.choice([0.0, rng.uniform(0, 8)])
        rovers.append(CollectRover(f"r{i + 1}", (rng.uniform(0, 200), rng.uniform(0, 200), z),
                                   z + rng.uniform(5, 40)))
    motion = Motion(rng.uniform(1, 3), None, rng.choice([0.0, 1.5]))  # fixed time: rovers on the ground
    problems = tuple(CollectProblem(_carrier(rng), motion, (rng.uniform(0, 200), rng.uniform(0, 200), 0.0),
                                    rng.uniform(-3, 3), tuple(rovers)) for _ in range(m))
    return TeamsProblem(tuple(f"c{k + 1}" for k in range(m)), problems)


# ------------------------------------------------------------------------------------ checks


def _retimed_equal(plan: Plan, p: DeployProblem | CollectProblem) -> None:
    again = retime(copy.deepcopy(plan), p.carrier, p.rover)
    assert again.makespan == pytest.approx(plan.makespan, abs=EPS)
    for s, t in zip(plan.stops, again.stops, strict=True):
        assert (s.arrive, s.depart) == pytest.approx((t.arrive, t.depart), abs=EPS)
        assert [leg.arrive for leg in s.rovers] == pytest.approx([leg.arrive for leg in t.rovers], abs=EPS)


def _independent_check(plan: Plan, p: DeployProblem | CollectProblem) -> None:
    """The JSON of one team's plan against tests/plan_checker (written from docs/time-model.md's text)."""
    c = p.carrier
    carrier = {"max_speed": c.max_speed, "accel": c.accel, "turn_rate": c.turn_rate,
               "unload_time": c.unload_time, "load_time": c.load_time, "takeoff_time": c.takeoff_time,
               "land_time": c.land_time}
    rover = {"max_speed": p.rover.max_speed, "accel": p.rover.accel, "fixed_time": p.rover.fixed_time}
    if isinstance(p, DeployProblem):
        got = check_plan(plan.to_json(), carrier, rover, p.deploy_range)
    else:
        got = check_plan(plan.to_json(), carrier, rover, {r.id: r.range for r in p.rovers},
                         {r.id: list(r.position) for r in p.rovers})
    assert got == pytest.approx(plan.makespan, abs=1e-3)


def check_teams(problem: TeamsProblem, out: TeamsPlan) -> None:
    """Every item exactly once; every team's plan valid under the time model, on its own deck,
    within its ranges, from its own start; makespan = the latest team's."""
    assert [t.carrier for t in out.teams] == list(problem.carriers)
    served: list[str] = []
    for k, team in enumerate(out.teams):
        p, plan = problem.problems[k], team.plan
        assert plan.start == p.start and plan.heading == p.heading
        legs = plan.legs()
        _retimed_equal(plan, p)
        if plan.stops:
            _independent_check(plan, p)
        for stop in plan.stops:
            for leg in stop.rovers:
                # a flight starts above the deck (take-off height) or ends above it (approach)
                h = p.takeoff_height if isinstance(p, DeployProblem) else p.approach_height
                end = leg.path[0 if problem.kind == "deploy" else -1]
                assert math.dist(end, (*stop.position[:2], h)) < EPS
        if isinstance(p, DeployProblem):
            rovers = [leg.rover for leg in legs]
            assert len(set(rovers)) == len(rovers) <= len(p.rovers) and set(rovers) <= set(p.rovers)
            where = {t.id: t.position for t in p.tasks}
            for leg in legs:
                assert leg.task is not None and math.dist(leg.end, where[leg.task]) < EPS
                assert path_length(leg.path) <= p.deploy_range + EPS
            served += [str(leg.task) for leg in legs]
        else:
            rng = {r.id: r for r in p.rovers}
            for leg in legs:
                assert math.dist(leg.start, rng[leg.rover].position) < EPS
                assert path_length(leg.path) <= rng[leg.rover].range + EPS
            served += [leg.rover for leg in legs]
    pool = problem.problems[0]
    every = [t.id for t in pool.tasks] if isinstance(pool, DeployProblem) else [r.id for r in pool.rovers]
    assert sorted(served) == sorted(every)
    assert out.makespan == max(t.plan.makespan for t in out.teams)


def _search_and_baseline(problem: TeamsProblem, planner: Any, screen: Any = None) -> None:
    out = plan_teams(problem, planner, "lee", max_calls=60, screen=screen)
    check_teams(problem, out)
    base = plan_teams_nearest(problem, planner, "lee")
    check_teams(problem, base)
    bound = teams_lower_bound(problem)
    assert out.baseline_makespan == pytest.approx(base.makespan, abs=EPS)
    assert out.makespan <= base.makespan + EPS  # never worse than the nearest carrier
    assert bound <= out.makespan + EPS and bound <= base.makespan + EPS


# ------------------------------------------------------------------------------------ properties


@pytest.mark.slow
@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(1, 14), m=st.integers(1, 4))
def test_deploy_allocation_properties(seed: int, n: int, m: int) -> None:
    _search_and_baseline(deploy_teams(seed, n, m, spare=seed % 3), DEPLOY_PLANNERS["lee"])


@pytest.mark.slow
@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(1, 12), m=st.integers(1, 3))
def test_collect_allocation_properties(seed: int, n: int, m: int) -> None:
    _search_and_baseline(collect_teams(seed, n, m), COLLECT_PLANNERS["lee"])


@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(1, 14), m=st.integers(1, 4), collect=st.booleans())
def test_screened_allocation_properties(seed: int, n: int, m: int, collect: bool) -> None:
    kind = "collect" if collect else "deploy"
    problem: TeamsProblem = (collect_teams(seed, min(n, 12), min(m, 3)) if collect
                             else deploy_teams(seed, n, m, spare=seed % 3))
    planner = (COLLECT_PLANNERS if collect else DEPLOY_PLANNERS)["lee"]
    _search_and_baseline(problem, planner, SCREEN_PLANNERS[kind]["lee"])


def test_a_screened_search_flies_the_planner_s_own_plans() -> None:
    """Candidate shares go to the screening form; the shares found and the baseline's are planned
    by the planner itself, and those are the plans returned."""
    problem = deploy_teams(11, 14, 3)
    calls = {"planner": 0, "screen": 0}

    def counted(name: str, fn: Any) -> Any:
        def call(p: DeployProblem) -> Plan:
            calls[name] += 1
            return fn(p)
        return call

    out = plan_teams(problem, counted("planner", DEPLOY_PLANNERS["lee"]), "lee",
                     screen=counted("screen", SCREEN_PLANNERS["deploy"]["lee"]))
    check_teams(problem, out)
    assert calls["planner"] <= 2 * problem.n_teams < calls["screen"]
    index = {t.id: i for i, t in enumerate(problem.problems[0].tasks)}
    for k, team in enumerate(out.teams):
        share = sorted(index[str(leg.task)] for leg in team.plan.legs())
        if share:
            own = DEPLOY_PLANNERS["lee"](problem.restrict(k, share))
            assert team.plan.makespan == pytest.approx(own.makespan, abs=EPS)
    base = plan_teams_nearest(problem, DEPLOY_PLANNERS["lee"], "lee")
    assert out.baseline_makespan == pytest.approx(base.makespan, abs=EPS)
    assert out.makespan <= base.makespan + EPS


@pytest.mark.slow
def test_tight_decks_hold_exactly_their_rovers() -> None:
    problem = deploy_teams(7, 12, 3, spare=0)
    out = plan_teams(problem, DEPLOY_PLANNERS["lee"], "lee", max_calls=80)
    check_teams(problem, out)
    assert sum(len(t.plan.legs()) for t in out.teams) == 12


def test_one_team_is_the_one_carrier_plan() -> None:
    problem = deploy_teams(3, 10, 1)
    out = plan_teams(problem, DEPLOY_PLANNERS["lee"], "lee")
    alone = DEPLOY_PLANNERS["lee"](problem.problems[0])
    assert out.makespan == pytest.approx(alone.makespan, abs=EPS)
    assert teams_lower_bound(problem) >= 0.0


def test_far_carrier_gets_nothing_and_search_beats_nearest() -> None:
    """A cluster of tasks next to one carrier's start but nearer (as the crow flies) to a slow
    carrier: the nearest-carrier baseline hands them to the slow one, the search does better."""
    tasks = tuple(Task(f"t{i + 1}", (100.0 + 10 * (i % 3), 10.0 * (i // 3), 0.0)) for i in range(9))
    fast = CarrierSpec(15.0, 10.0, 3.0, 4.0, 4.0)
    slow = CarrierSpec(1.0, None, None, 4.0, 4.0)
    deck = tuple(f"r{i + 1}" for i in range(9))
    problems = (DeployProblem(fast, Motion(1.0), 20.0, (0.0, 0.0, 0.0), 0.0, tasks, deck),
                DeployProblem(slow, Motion(1.0), 20.0, (140.0, 0.0, 0.0), 0.0, tasks,
                              tuple(f"r{i + 10}" for i in range(9))))
    problem = TeamsProblem(("fast", "slow"), problems)
    out = plan_teams(problem, DEPLOY_PLANNERS["lee"], "lee")
    check_teams(problem, out)
    assert out.baseline_makespan is not None and out.makespan < out.baseline_makespan - 1.0


def test_roadmap_teams_avoid_obstacles(tmp_path: Path) -> None:
    """lee-graph plans every team among obstacles; the allocation properties hold there too."""
    import yaml

    d = yaml.safe_load((ROOT / "missions/paper/roadmap_outdoor_obstacles.yaml").read_text())
    one = d.pop("carrier")
    del d["rovers"]["fleet"], d["collection"]
    d["carriers"] = [{**one, "id": "c1", "fleet": {"count": 4}},
                     {**one, "id": "c2", "sysid": 2, "position": [80, 85], "fleet": {"count": 4}}]
    problem = teams_problem(load(tmp_path, d), "deploy")
    out = plan_teams(problem, DEPLOY_PLANNERS["lee-graph"], "lee-graph", max_calls=12)
    check_teams(problem, out)
    assert out.baseline_makespan is not None and out.makespan <= out.baseline_makespan + EPS
    obstacles = [p for team in problem.problems for p in team.obstacles]
    assert obstacles and all(t.plan.planner == "lee-graph" and t.plan.roadmap is not None for t in out.teams)
    for t in out.teams:  # every carrier and rover segment clear of the obstacles (detours or none)
        assert_outside(t.plan.to_json(), obstacles)


def test_too_few_rovers_on_the_decks_is_refused() -> None:
    from planners.core.problem import PlanningError

    problem = deploy_teams(1, 6, 2, spare=0)
    short = TeamsProblem(problem.carriers, (replace(problem.problems[0], rovers=("r1",)),
                                            replace(problem.problems[1], rovers=("r2",))))
    with pytest.raises(PlanningError, match="6 tasks need as many rovers"):
        plan_teams(short, DEPLOY_PLANNERS["lee"], "lee")


def test_teams_json_shape() -> None:
    problem = deploy_teams(5, 8, 2)
    data = json.loads(json.dumps(plan_teams(problem, DEPLOY_PLANNERS["lee"], "lee").to_json()))
    assert set(data) == {"schema", "kind", "planner", "allocation", "teams", "makespan", "compute_ms"}
    assert data["schema"] == "fleetctl.plan/1" and data["kind"] == "deploy" and data["planner"] == "lee"
    for team in data["teams"]:
        assert set(team) == {"carrier", "start", "heading", "stops", "makespan", "carrier_distance",
                             "time_model"}
        assert {"takeoff_time", "land_time", "rover_fixed_time"} <= set(team["time_model"])
        for stop in team["stops"]:
            assert set(stop) == {"position", "arrive", "depart", "carrier_path", "rovers"}
            for r in stop["rovers"]:
                assert set(r) == {"rover", "task", "target", "path", "arrive"}
    assert data["makespan"] == max(t["makespan"] for t in data["teams"])


# ------------------------------------------------------------------------------------ mission keys

TEAM = {"sysid": 1, "position": [0, 0], "max_speed": 15.0, "fleet": {"count": 2}}


RADIO = "udpin://0.0.0.0:14550"  # one radio network both carriers share (one system-id space)


def teams_mission(*carriers: dict[str, Any], **top: Any) -> dict[str, Any]:
    data = copy.deepcopy(BASE)
    del data["carrier"]
    data["carriers"] = [dict(c) for c in carriers]
    data.update(top)
    return data


def c(id: str, sysid: int, **kv: Any) -> dict[str, Any]:
    """A carriers[i] entry; a keyword set to None leaves that key out."""
    return {k: v for k, v in {**TEAM, "id": id, "sysid": sysid, **kv}.items() if v is not None}


def test_example_mission_loads(tmp_path: Path) -> None:
    m = load_mission(TWO)
    teams = mission_teams(m)
    assert [t.carrier.id for t in teams] == ["c1", "c2"] and several_teams(m)
    assert teams[0].rovers == tuple(f"r{i}" for i in range(1, 9))
    assert teams[1].rovers == tuple(f"r{i}" for i in range(9, 17))
    sysids = {u.id: u.sysid for u in m.rovers.units}
    assert (sysids["r1"], sysids["r8"], sysids["r9"], sysids["r16"]) == (11, 18, 31, 38)
    assert teams[1].carrier.position == (200.0, 0.0) and m.carrier.id == "c1"
    problem = teams_problem(m, "deploy")
    assert problem.carriers == ("c1", "c2") and problem.problems[1].start == (200.0, 0.0, 0.0)
    assert problem.problems[1].rovers == teams[1].rovers


def test_fleet_ids_and_sysids_run_on(tmp_path: Path) -> None:
    m = load(tmp_path, teams_mission(c("c1", 1), c("c2", 2, fleet={"count": 3})))
    assert [(u.id, u.sysid) for u in m.rovers.units] == [("r1", 11), ("r2", 12), ("r3", 13), ("r4", 14),
                                                        ("r5", 15)]
    assert [t.rovers for t in m.teams] == [("r1", "r2"), ("r3", "r4", "r5")]


def test_units_per_carrier(tmp_path: Path) -> None:
    units = [{"id": "a1", "sysid": 40}, {"id": "a2", "sysid": 41}]
    m = load(tmp_path, teams_mission(c("c1", 1), c("c2", 2, fleet=None, units=units)))
    assert m.teams[1].rovers == ("a1", "a2")


def test_one_team_list_is_today_s_carrier(tmp_path: Path) -> None:
    origin = {"lat": 47.397742, "lon": 8.545594, "alt": 488.0}
    listed = load(tmp_path, teams_mission(c("carrier", 1, fleet={"count": 2}), origin=origin))
    (tmp_path / "one").mkdir()
    single = load(tmp_path / "one", {**copy.deepcopy(BASE), "origin": origin})
    assert not several_teams(listed)
    assert listed.deploy_problem() == single.deploy_problem()
    from fleetctl.run.sim import sim_mission_dict
    from sitl import FleetConfig

    cfg = FleetConfig.from_mission_dict(sim_mission_dict(listed))
    assert cfg.carrier.sysid == 1 and [r.id for r in cfg.rovers] == ["r1", "r2"]


@pytest.mark.parametrize(("data", "where", "what"), [
    (teams_mission(c("c1", 1), carrier=BASE["carrier"]), "carriers:", "not both"),
    ({k: v for k, v in BASE.items() if k != "carrier"}, "carrier:", "required key is missing"),
    (teams_mission(), "carriers:", "the list is empty"),
    (teams_mission(c("c1", 1), c("c1", 2)), "carriers[1].id:", "duplicate vehicle id 'c1'"),
    (teams_mission(c("c1", 1, connection=RADIO), c("c2", 1, connection=RADIO)), "carriers[1].sysid:",
     "duplicate vehicle sysid 1"),
    (teams_mission(c("c1", 1, connection=RADIO),
                   c("c2", 2, connection=RADIO, fleet={"count": 2, "sysid_start": 12})),
     "carriers[1].fleet.sysid_start:", "duplicate vehicle sysid 12"),
    (teams_mission(c("c1", 1, connection=RADIO),
                   c("c2", 11, connection=RADIO, fleet={"count": 2, "sysid_start": 40})),
     "carriers[0].fleet.sysid_start:", "duplicate vehicle sysid 11"),
    (teams_mission(c("c1", 1, fleet={"count": 1})), "carriers:",
     "only 1 rover(s) on the carriers for 2 tasks"),
    (teams_mission(c("c1", 1), c("c2", 2, fleet=None)), "carriers[1].fleet:", "required key is missing"),
    (teams_mission(c("c1", 1), c("c2", 2, fleet={"sysid_start": 50})), "carriers[1].fleet.count:",
     "required key is missing"),
    (teams_mission(c("c1", 1, units=[{"id": "x", "sysid": 60}])), "carriers[0].units:", "not both"),
    (teams_mission(c("c1", 1), c("c2", 2, fleet=None, units=[{"id": "r1", "sysid": 60}])),
     "carriers[1].units[0].id:", "duplicate vehicle id 'r1'"),
    (teams_mission(c("c1", 1), c("c2", 2, fleet=None, units=[])), "carriers[1].units:", "empty"),
    (teams_mission(c("c1", 1), rovers={**BASE["rovers"], "fleet": {"count": 2}}), "rovers.fleet:",
     "every carrier lists its own rovers"),
    (teams_mission(c("c1", 1), c("c2", 2, connection="udp://127.0.0.1:14550")), "carriers[1].connection:",
     "mixes a simulated and a real fleet"),
    (teams_mission(c("c1", 1), {**c("c2", 2), "fleat": {"count": 2}}), "carriers[1].fleat:",
     "did you mean 'fleet'?"),
    (teams_mission(c("c1", 1), {k: v for k, v in c("c2", 2).items() if k != "id"}), "carriers[1].id:",
     "required key is missing"),
    (teams_mission(c("c1", 1), c("c2", 2, position=[25, 25]), obstacles=[[[20, 20], [30, 20], [30, 30]]],
                   bounds=[[-10, -10], [100, 100]]), "carriers[1].position:", "inside obstacles[0]"),
    (teams_mission(c("c1", 1), c("c2", 2, fleet={"count": 2, "sysid_start": 255})),
     "carriers[1].fleet.sysid_start:", "exceed 255"),
    (teams_mission(c("c1", 1), collection={"rovers": [{"id": "r9", "position": [1, 1], "range": 5}]}),
     "collection.rovers[0].id:", "not a rover of the fleet"),
])
def test_carriers_validation(tmp_path: Path, data: dict[str, Any], where: str, what: str) -> None:
    msg = error(tmp_path, data)
    assert where in msg and what in msg, msg


def test_faults_may_name_any_carrier(tmp_path: Path) -> None:
    faults = {"faults": [{"vehicle": "c2", "kind": "dropout"}]}
    m = load(tmp_path, teams_mission(c("c1", 1), c("c2", 2), sim=faults))
    assert m.sim.faults[0].vehicle == "c2"


# ------------------------------------------------------------------------------------ command line


def test_plan_json_on_two_carriers(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "--mission", str(TWO), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["schema"] == "fleetctl.plan/1" and [t["carrier"] for t in data["teams"]] == ["c1", "c2"]
    m = load_mission(TWO)
    tasks = sorted(r["task"] for t in data["teams"] for s in t["stops"] for r in s["rovers"])
    assert tasks == sorted(t.id for t in m.tasks)
    for team, cfg in zip(data["teams"], mission_teams(m), strict=True):
        k = replace(m, carrier=cfg.carrier).carrier_spec()
        one = {"schema": data["schema"], "kind": "deploy", "carrier": {"start": team["start"],
                                                                       "heading": team["heading"]},
               "stops": team["stops"], "makespan": team["makespan"]}
        one["time_model"] = team["time_model"]
        got = check_plan(one, {"max_speed": k.max_speed, "accel": k.accel, "turn_rate": k.turn_rate,
                               "unload_time": k.unload_time, "load_time": k.load_time,
                               "takeoff_time": k.takeoff_time, "land_time": k.land_time},
                         {"max_speed": m.rovers.max_speed, "accel": m.rovers.accel}, m.rovers.deploy_range)
        assert got == pytest.approx(team["makespan"], abs=1e-3)
        assert {r["rover"] for s in team["stops"] for r in s["rovers"]} <= set(cfg.rovers)


def test_plan_summary_collect_and_plot(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    png = tmp_path / "two.png"
    assert main(["plan", "--mission", str(TWO), "--collect", "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    for word in ("team c1", "team c2", "makespan", "nearest carrier", "lower bound", "plot written"):
        assert word in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_export_of_several_teams_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "--mission", str(TWO), "--export", str(tmp_path / "x")]) == 2
    assert "exporting several teams is not supported yet" in capsys.readouterr().err


def test_status_checks_every_carrier_and_its_rovers(capsys: pytest.CaptureFixture[str]) -> None:
    """``status`` of two teams: the embedded simulated fleet of both carriers, every vehicle checked
    (each carrier as a carrier, each rover on a deck), one object per vehicle."""
    import json

    assert main(["status", "--mission", str(TWO), "--json", "--timeout", "10"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    by_id = {r["vehicle"]: r for r in rows}
    assert set(by_id) == {"c1", "c2", *(f"r{i}" for i in range(1, 17))}
    assert by_id["c1"]["role"] == by_id["c2"]["role"] == "carrier"
    assert by_id["c2"]["sysid"] == 2 and by_id["r9"]["sysid"] == 31
    assert all(r["ready"] for r in rows), [r for r in rows if not r["ready"]]
    assert all(by_id[f"r{i}"]["on_deck"] is True for i in range(1, 17))  # r9..r16 on c2's deck, 200 m off c1


def test_a_planner_that_cannot_serve_the_shares_is_one_line() -> None:
    import subprocess
    import sys

    cmd = [sys.executable, "-m", "fleetctl.cli", "plan", "-m", str(TWO), "--planner", "two-task"]
    res = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert res.returncode == 2 and res.stderr.count("\n") == 1, res.stderr
    assert "cannot plan with 'two-task'" in res.stderr


def test_team_mission_is_one_team_of_the_file() -> None:
    from fleetctl.mission import load_mission
    from fleetctl.mission.model import MissionError
    from fleetctl.mission.teams import team_mission

    m = load_mission(Path(__file__).resolve().parents[2] / "missions" / "two_carriers.yaml")
    t = team_mission(m, "c2", tasks=["t11", "t12"])
    assert t.carrier.id == "c2" and t.carrier.sysid == 2 and t.teams == ()
    assert t.rovers.ids == tuple(f"r{i}" for i in range(9, 17))
    assert [x.id for x in t.tasks] == ["t11", "t12"]
    assert t.collection is not None and {r.id for r in t.collection} <= set(t.rovers.ids)
    assert "carriers" not in t.raw and t.raw["carrier"]["id"] == "c2"
    assert [u["sysid"] for u in t.raw["rovers"]["units"]] == list(range(31, 39))
    both = team_mission(m, "c1", rovers=["r1", "r9"])  # a collection may hand a team another deck's rover
    assert both.rovers.ids == ("r1", "r9") and {r.id for r in both.collection or ()} == {"r1", "r9"}
    with pytest.raises(MissionError, match="no carrier 'c3'"):
        team_mission(m, "c3")


def test_team_mission_keeps_its_own_vehicles_sim_faults(tmp_path: Path) -> None:
    import yaml

    from fleetctl.mission import load_mission
    from fleetctl.mission.teams import team_mission
    from fleetctl.run.sim import sim_mission_dict
    from sitl import FleetConfig

    d = yaml.safe_load(TWO.read_text())
    d["sim"]["faults"] = [{"kind": "dropout", "vehicle": "c2", "at": 5},
                          {"kind": "dropout", "vehicle": "r1", "at": 9}, {"kind": "packet_loss", "rate": 0.1}]
    path = tmp_path / "faults.yaml"
    path.write_text(yaml.safe_dump(d), encoding="utf-8")
    m = load_mission(path)
    for team, kept in (("c1", ["r1", None]), ("c2", ["c2", None])):
        own = team_mission(m, team)
        assert [f.get("vehicle") for f in own.raw["sim"]["faults"]] == kept
        FleetConfig.from_mission_dict(sim_mission_dict(own, "deploy"))  # that team's simulator starts


def test_each_team_plans_the_touch_down_onto_its_own_deck(tmp_path: Path) -> None:
    import yaml

    from fleetctl.mission.flight import LAND_SETTLE, descent
    from fleetctl.mission.teams import team_mission

    d = yaml.safe_load(TWO.read_text())
    d["carriers"][1]["deck_height"] = 1.0  # c2's deck stands 1 m up, c1's on the ground
    path = tmp_path / "decks.yaml"
    path.write_text(yaml.safe_dump(d), encoding="utf-8")
    m = load_mission(path)
    land = m.rovers.land_speed
    ones = {team.carrier.id: p for team, p in zip(mission_teams(m), teams_problem(m, "collect").problems,
                                                  strict=True)}
    assert ones["c1"].carrier.land_time == pytest.approx(descent(0.0) / land + LAND_SETTLE)
    assert ones["c2"].carrier.land_time == pytest.approx(descent(1.0) / land + LAND_SETTLE)
    assert team_mission(m, "c2").rovers.land_time == pytest.approx(descent(1.0) / land + LAND_SETTLE)
    d["rovers"]["land_time"] = 4.0  # given in the file: every team's, whatever its deck
    path.write_text(yaml.safe_dump(d), encoding="utf-8")
    given = load_mission(path)
    assert {p.carrier.land_time for p in teams_problem(given, "collect").problems} == {4.0}
