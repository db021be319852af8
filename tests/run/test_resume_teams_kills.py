"""``fleetctl resume --run DIR`` of several teams killed at the moments
:mod:`tests.run.test_resume_teams` leaves out (docs/teams.md#resume):

* a two-team ``collect`` killed during its collection: resumed, every rover is loaded once and
  the summary says so;
* a ``run --team`` controller on a real mosquitto killed during its collection while the other
  team's controller flies on: resumed, it re-joins the bus and collects its own rovers, once;
* a two-team ``deploy`` in which c1's carrier is lost (its link drops out for good), killed after
  c1 gave its tasks up: resumed, the hand-over holds - c2 flies them, c1 flies nothing.

The fleet is ``fleetctl sim`` in its own process (it outlives the controller, as a real fleet does).
"""

from __future__ import annotations

import math
import signal
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.bus.test_bus import MOSQUITTO, Broker
from tests.run.resume_helpers import (
    Problems,
    Records,
    controller,
    launch_violations,
    of_kind,
    parse_journal_strict,
    read_summary,
    run_ctl,
    sim_process,
)
from tests.run.test_resume_teams import (
    REACH,
    ROVERS,
    TASKS,
    TEAMS,
    _partial,
    check_team_controller_resumed,
    describe,
    journal_texts,
    journals,
    observe,
    team_records,
    wait_journals,
    write_two_teams,
)

pytestmark = pytest.mark.slow

SPEEDUP = 8.0
VEHICLES = len(TEAMS) + len(ROVERS)


def _fast(tmp_path: Path, **changes: Any) -> tuple[Path, dict[str, Any]]:
    mission, d = write_two_teams(tmp_path)
    d["sim"]["speedup"] = SPEEDUP
    d["rovers"]["endurance_range"] = 5000.0  # batteries that outlast the test's hovering
    d["planner"] = {"budget_ms": 0}  # the quick plans: the test is about the records, not the plans
    d.update(changes)
    mission.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
    return mission, d


def _fly(args: list[str], mission: Path, run_dir: Path, log: Path) -> None:
    rc, out = run_ctl([*args, "--mission", str(mission), "--run-dir", str(run_dir), "--headless", "--yes"],
                      log)
    assert rc == 0, out[-3000:]


def _appended(p: Problems, run_dir: Path, before: dict[str, str]) -> None:
    after = journal_texts(run_dir)
    for name, text in before.items():  # appended to, never rewritten
        p.check(after.get(name, "").startswith(text[: text.rfind("\n") + 1]), f"resume rewrote {name}")


def _collection_started(js: dict[str, Records]) -> bool:
    col = team_records(js, "collect")
    i = next((k for k, r in enumerate(col) if r.get("kind") == "collection_started"), None)
    return i is not None and bool(of_kind(col[i:], "command"))


# ---------------------------------------------------------------------------------------------------
# (a) a two-team collect
# ---------------------------------------------------------------------------------------------------

def test_kill_9_a_two_team_collect_then_resume_loads_every_rover_once(tmp_path: Path) -> None:
    """Both teams deployed (``deploy``), then ``collect`` of the mission with a ``collection:``
    section naming every rover where it holds, killed once a team's collection commands; resumed,
    every rover is loaded once (in the teams' collection journals) and sits on a carrier's deck."""
    mission, d = _fast(tmp_path)
    col = tmp_path / "collect"
    with sim_process(mission, tmp_path / "sim.log", speedup=SPEEDUP, vehicles=VEHICLES) as sim:
        _fly(["deploy"], mission, tmp_path / "deploy", tmp_path / "deploy.log")
        deployed = team_records(journals(tmp_path / "deploy"), "deploy")
        on_task = {r["vehicle"]: r["task"] for r in of_kind(deployed, "task_reached")}
        where = {t["id"]: t["position"] for t in d["tasks"]}
        d["collection"] = {"rovers": [{"id": rid, "position": where[on_task[rid]], "range": 300.0}
                                      for rid in ROVERS]}
        mission.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
        with controller(["collect", "--mission", str(mission), "--run-dir", str(col), "--headless", "--yes"],
                        tmp_path / "collect.log") as fly:
            wait_journals(fly, col, _collection_started, "a command after a team's collection_started")
            assert fly.kill9() == -signal.SIGKILL
        killed = journals(col)
        loaded_before = {r["vehicle"] for r in of_kind(team_records(killed, "collect"), "rover_loaded")}
        assert len(loaded_before) < len(ROVERS), "every rover loaded before the kill (test timing)"
        before = journal_texts(col)
        rc, out = run_ctl(["resume", "--run", str(col), "--headless", "--yes"], tmp_path / "resume.log")
        seen = observe(mission)
        assert sim.proc.poll() is None, sim.output()
    p = Problems()
    p.check(rc == 0, f"resume exited {rc}")
    p.check("Traceback" not in out, "a traceback in the output of resume")
    _appended(p, col, before)
    js = journals(col)
    p.check(len(of_kind(parse_journal_strict(col), "resumed")) == 1, "no single 'resumed' record (run's)")
    loaded = Counter(r["vehicle"] for r in of_kind(team_records(js, "collect"), "rover_loaded"))
    p.check(loaded == Counter(dict.fromkeys(ROVERS, 1)), f"rovers loaded {dict(loaded)} (want each once)")
    p.check(not of_kind(team_records(js, "collect"), "rover_launched"), "a collection launched a rover")
    summary = read_summary(col)
    p.check(summary.get("result") == "complete", f"summary result {summary.get('result')!r}")
    p.check(sorted(summary.get("rovers_loaded", [])) == ROVERS, f"summary rovers_loaded "
            f"{summary.get('rovers_loaded')}")
    teams = {t["carrier"]: t for t in summary.get("teams", [])}
    p.check(all("deploy" not in t for t in teams.values()), f"a collect summary with a deployment: {teams}")
    off = [rid for rid, s in seen.items() if s.deck is None]
    p.check(not off, f"the world: rovers not on a carrier's deck: {off}")
    p.assert_none(f"loaded before the kill: {sorted(loaded_before)}", f"resume output:\n{out[-3000:]}")


# ---------------------------------------------------------------------------------------------------
# (c) a carrier lost, its tasks handed over, then the controller killed
# ---------------------------------------------------------------------------------------------------

LOST_SPEEDUP = 4.0
DROPOUT_AT = 60.0  # s of simulated time: c1's link drops out for good (about 15 s after the sim starts)


def _lost_carrier_mission(tmp_path: Path) -> tuple[Path, dict[str, Any]]:
    """c1's two tasks far north (a long drive, during which its link drops out for good), c2's two
    near it; c2 has four rovers, two to spare for c1's tasks."""
    mission, d = _fast(tmp_path)
    d["sim"] = {"speedup": LOST_SPEEDUP, "faults": [{"kind": "dropout", "vehicle": "c1", "at": DROPOUT_AT}]}
    d["carriers"][1]["fleet"] = {"count": 4, "sysid_start": 31}
    d["tasks"] = [{"id": "t1", "position": [-5, 400, 5]}, {"id": "t2", "position": [5, 460, 4]},
                  {"id": "t3", "position": [75, 30, 5]}, {"id": "t4", "position": [85, 90, 4]}]
    d["links"] = {"heartbeat_timeout": 2.0, "reassign_after": 1.0}
    mission.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
    return mission, d


def _handed_by_c1(js: dict[str, Records]) -> bool:
    return any(r.get("from_team") == "c1" and r.get("to_team") == "c2"
               for r in of_kind(js["run"], "handover"))


def test_kill_9_while_a_carrier_is_lost_then_resume_honours_the_handover(tmp_path: Path) -> None:
    """c1's carrier drops out for good while it deploys; c1 gives its tasks up and c2 is handed
    them; the controller is killed right after the ``handover`` record. Resumed (c1 still lost),
    every task is reached once, c1's by c2's rovers; c1 launches nothing; the summary has the
    hand-over and c1 lost."""
    mission, d = _lost_carrier_mission(tmp_path)
    rovers = ["r1", "r2", "r3", "r4", "r5", "r6"]
    run_dir = tmp_path / "run"
    with sim_process(mission, tmp_path / "sim.log", speedup=LOST_SPEEDUP, vehicles=2 + len(rovers)) as sim:
        args = ["deploy", "--mission", str(mission), "--run-dir", str(run_dir), "--headless", "--yes"]
        with controller(args, tmp_path / "fly.log") as fly:
            wait_journals(fly, run_dir, _handed_by_c1, "a handover record from c1 to c2")
            assert fly.kill9() == -signal.SIGKILL
        killed = journals(run_dir)
        assert [r["vehicle"] for r in of_kind(killed["run"], "carrier_lost")] == ["c1"], \
            "c1's link dropped out before its deployment began (test timing: a slow controller start)"
        (h,) = [r for r in of_kind(killed["run"], "handover") if r.get("from_team") == "c1"]
        handed = sorted(h["tasks"])
        assert handed, h
        assert not set(handed) & {r["task"] for r in of_kind(team_records(killed, "deploy"), "task_reached")}
        before = journal_texts(run_dir)
        # --timeout 3: c1 does not answer; the resume waits 3 s for it, not the default 10
        rc, out = run_ctl(["resume", "--run", str(run_dir), "--headless", "--yes", "--timeout", "3"],
                          tmp_path / "resume.log")
        seen = observe(mission, rovers=rovers)
        assert sim.proc.poll() is None, sim.output()
    p = Problems()
    p.check(rc == 0, f"resume exited {rc}")
    p.check("Traceback" not in out, "a traceback in the output of resume")
    _appended(p, run_dir, before)
    js = journals(run_dir)
    dep = team_records(js, "deploy")
    reached = Counter(r["task"] for r in of_kind(dep, "task_reached"))
    p.check(reached == Counter(dict.fromkeys(TASKS, 1)), f"tasks reached {dict(reached)} (each once)")
    by_c2 = {r["task"] for r in of_kind(js.get("c2/deploy", []), "task_reached")}
    p.check(set(handed) <= by_c2, f"handed {handed}: c2 reached {sorted(by_c2)}")
    c1_after = js.get("c1/deploy", [])[len(killed.get("c1/deploy", [])):]
    p.check(not of_kind(c1_after, "launch", "rover_launched"), "c1 launched a rover after the resume")
    launched = Counter(r["vehicle"] for r in of_kind(dep, "rover_launched"))
    p.check(all(n == 1 for n in launched.values()), f"rovers launched {dict(launched)}")
    for key, recs in js.items():
        for v in launch_violations(recs):
            p.check(False, f"{key}: {v}")
    summary = read_summary(run_dir)
    p.check(summary.get("result") == "complete", f"summary result {summary.get('result')}")
    lost = {t["carrier"]: t["lost"] for t in summary.get("teams", [])}
    p.check(lost == {"c1": True, "c2": False}, f"summary teams lost {lost}")
    p.check(any(x["from"] == "c1" and x["to"] == "c2" and sorted(x["tasks"]) == handed
                for x in summary.get("handovers", [])), f"summary handovers {summary.get('handovers')}")
    on_task = {t["id"]: [rid for rid, s in seen.items() if s.enu is not None
                         and math.dist(s.enu, t["position"]) <= REACH] for t in d["tasks"]}
    p.check(all(len(v) == 1 for v in on_task.values()), f"the world: rovers on each task {on_task}")
    p.assert_none(f"handed over before the kill: {handed}", f"the world:\n{describe(seen)}",
                  f"resume output:\n{out[-3000:]}")


# ---------------------------------------------------------------------------------------------------
# (b) a run --team controller on the bus killed during its collection
# ---------------------------------------------------------------------------------------------------

def _team_collecting(recs: Records) -> bool:
    i = next((k for k, r in enumerate(recs) if r.get("kind") == "collection_started"), None)
    return i is not None and bool(of_kind(recs[i:], "command"))


def _team_dwelling(recs: Records) -> bool:
    return bool(of_kind(recs, "dwell"))


TEAM_MOMENTS = {  # the dwell, the collection's wait: kill when, then what must not have happened yet
    "dwell": (["--dwell", "3"], _team_dwelling, "collection_started"),
    "collection": (["--dwell", "1"], _team_collecting, "collected"),
}


@pytest.mark.skipif(MOSQUITTO is None, reason="mosquitto binary not installed")
@pytest.mark.parametrize("moment", list(TEAM_MOMENTS))
def test_kill_9_a_run_team_controller_then_resume_collects_its_rovers(tmp_path: Path, moment: str) -> None:
    """Both teams' controllers (``run --team``) on a real mosquitto; c1's is killed during its
    dwell or once its collection commands, and resumed while c2's flies on: c1 re-joins the bus (a
    new session) and loads each of its rovers once; every task was reached once, every rover is on
    a deck."""
    dwell, until, not_yet = TEAM_MOMENTS[moment]
    broker = Broker(tmp_path)
    broker.start()
    try:
        mission, d = write_two_teams(tmp_path, links=2)  # each controller on its own team's link
        d["sim"]["speedup"] = SPEEDUP
        d["rovers"]["endurance_range"] = 5000.0
        d["planner"] = {"budget_ms": 0}
        d["mqtt"] = {"url": broker.url, "topic_prefix": "test/resume-run-team"}
        mission.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
        d1, d2 = tmp_path / "c1", tmp_path / "c2"
        team = ["--mission", str(mission), *dwell, "--headless", "--yes"]
        with sim_process(mission, tmp_path / "sim.log", speedup=SPEEDUP, vehicles=VEHICLES) as sim, \
                controller(["run", "--team", "c2", *team, "--run-dir", str(d2)], tmp_path / "c2.log") as c2:
            with controller(["run", "--team", "c1", *team, "--run-dir", str(d1)], tmp_path / "c1.log") as c1:
                wait_journals(c1, d1, lambda _js: until(_partial(d1 / "journal.jsonl")), f"c1's {moment}")
                assert c1.kill9() == -signal.SIGKILL
            killed = parse_journal_strict(d1)
            assert not of_kind(killed, not_yet), f"c1's {not_yet} before the kill (test timing)"
            rc, out = run_ctl(["resume", "--run", str(d1), "--headless", "--yes"], tmp_path / "resume.log")
            rc2 = c2.wait()
            seen = observe(mission)
            assert sim.proc.poll() is None, sim.output()
    finally:
        broker.stop()
    p = Problems()
    r1, r2, after = check_team_controller_resumed(p, (rc, rc2), out, (d1, d2), killed)
    p.check(not of_kind(after, "launch", "rover_launched"), "c1 launched a rover after the resume")
    loaded = Counter(r["vehicle"] for r in of_kind(r1, "rover_loaded"))
    p.check(loaded == Counter(dict.fromkeys(TEAMS["c1"], 1)), f"c1 loaded {dict(loaded)} (want r1, r2 once)")
    summary = read_summary(d1)
    p.check(summary.get("result") == "complete", f"c1's summary result {summary.get('result')}")
    off = [rid for rid, s in seen.items() if s.deck is None]
    p.check(not off, f"the world: rovers not on a carrier's deck: {off}")
    p.assert_none(f"the world:\n{describe(seen)}", f"resume output:\n{out[-3000:]}")
