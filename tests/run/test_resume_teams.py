"""``fleetctl resume --run DIR`` of a run of several teams (docs/teams.md#resume).

The two-team mission of :mod:`tests.teams.teams_helpers` (c1 and c2, two rovers each, two tasks
near each carrier) on real UDP URLs, its simulated fleet served by ``fleetctl sim`` in its own
process (so it outlives the controller, as a real fleet does). The controller (``fleetctl deploy``
or ``run``, every team in one process) is killed with SIGKILL at a chosen moment of its journals
(the run's ``RUN/journal.jsonl`` and each team's ``RUN/teams/<carrier>/<phase>/journal.jsonl``),
then ``fleetctl resume --run DIR`` must finish the run:

* every journal appended to, never rewritten; one ``resumed`` record in the run's journal;
* no task reached twice, no rover launched twice (across every team's journal), every task
  reached;
* the summary complete, and the simulated world (a fresh MAVLink connection) agrees: after a
  ``deploy`` one rover on each task, the one the journals launched for it; after a ``run`` every
  rover on a carrier's deck, loaded once.

The moments: before a team's first launch, after a launch, in a launch's write-ahead window,
mid-deployment of a ``run`` (then the dwell and the collection), during the dwell, during the
collection, right after a hand-over record (the handed task is flown once, by its new team), and
a resume killed in turn. A ``--team`` controller killed and resumed flies its own share (or
collects its own deck) only, and with a real mosquitto re-joins the bus while the other team
flies on. Resume refuses what it cannot finish in one line.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import signal
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.bus.test_bus import MOSQUITTO, Broker
from tests.run.ctl_helpers import free_udp_port
from tests.run.resume_helpers import (
    Problems,
    Records,
    controller,
    first_output_line_names,
    launch_violations,
    of_kind,
    parse_journal_strict,
    read_summary,
    run_ctl,
    sim_process,
)
from tests.run.teams.teams_helpers import two_teams

pytestmark = pytest.mark.slow

TASKS = ["t1", "t2", "t3", "t4"]
TEAMS = {"c1": ["r1", "r2"], "c2": ["r3", "r4"]}
ROVERS = [r for rs in TEAMS.values() for r in rs]
REACH = 1.5  # m: a rover this close (3D) to a task is on it
DECK = 1.5  # m: a landed rover this close (horizontally) to a carrier is on its deck
POLL = 0.005  # s between looks at the journals
WAIT = 60.0  # s: bound of every wait (never a timing assertion)


def write_two_teams(tmp_path: Path, links: int = 1) -> tuple[Path, dict[str, Any]]:
    """Both carriers and their rovers on one UDP URL (``links`` 2: each team on its own), the sim
    at 5x; each team's two tasks 60 m apart in a row north of its carrier, ``deploy_range`` 15 m:
    each team plans two stops of one launch each."""
    d = two_teams(tasks=[{"id": "t1", "position": [-5, 30, 5]}, {"id": "t2", "position": [5, 90, 4]},
                         {"id": "t3", "position": [75, 30, 5]}, {"id": "t4", "position": [85, 90, 4]}])
    d["rovers"]["deploy_range"] = 15.0
    urls = [f"udp://127.0.0.1:{free_udp_port()}" for _ in range(links)]
    for k, c in enumerate(d["carriers"]):
        c["connection"] = urls[k % links]
    d["sim"]["speedup"] = 5.0
    path = tmp_path / "two.yaml"
    path.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
    return path, d


# ---------------------------------------------------------------------------------------------------
# the journals
# ---------------------------------------------------------------------------------------------------

def _partial(path: Path) -> Records:
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return []
    out: Records = []
    for line in text.split("\n")[:-1]:  # the part after the last newline may be half written
        with contextlib.suppress(ValueError):
            out.append(json.loads(line))
    return out


def journals(run_dir: Path) -> dict[str, Records]:
    """"run" -> the run's journal, "<carrier>/<phase>" -> each team's (whole lines only)."""
    out = {"run": _partial(run_dir / "journal.jsonl")}
    for path in sorted((run_dir / "teams").glob("*/*/journal.jsonl")):
        out[f"{path.parent.parent.name}/{path.parent.name}"] = _partial(path)
    return out


def team_records(js: dict[str, Records], phase: str) -> Records:
    return [r for key, recs in js.items() if key.endswith("/" + phase) for r in recs]


def journal_texts(run_dir: Path) -> dict[str, str]:
    return {str(p.relative_to(run_dir)): p.read_text(encoding="utf-8")
            for p in run_dir.rglob("journal.jsonl")}


def wait_journals(ctl: Any, run_dir: Path, until: Callable[[dict[str, Records]], bool], what: str) -> None:
    deadline = time.monotonic() + WAIT
    while not until(journals(run_dir)):
        if ctl.proc.poll() is not None:
            raise AssertionError(f"the controller exited ({ctl.proc.returncode}) before {what}:\n"
                                 f"{ctl.tail()}")
        if time.monotonic() > deadline:
            raise AssertionError(f"no {what} in the journals after {WAIT} s:\n{ctl.tail()}")
        time.sleep(POLL)


# ---------------------------------------------------------------------------------------------------
# the world
# ---------------------------------------------------------------------------------------------------

@dataclass
class Seen:
    enu: tuple[float, float, float] | None
    on_ground: bool | None
    deck: str | None  # the carrier on whose deck it sits


def observe(mission_path: Path, timeout: float = 8.0, rovers: list[str] = ROVERS) -> dict[str, Seen]:
    """Every rover as its telemetry shows it now (a second GCS on the sim's links)."""
    return asyncio.run(_observe(mission_path, timeout, rovers))


async def _observe(mission_path: Path, timeout: float, rovers: list[str]) -> dict[str, Seen]:
    from fleetctl.mavlink.fleet import connect_fleet
    from fleetctl.mission import load_mission

    # a vehicle not heard (a carrier lost for good) is seen nowhere
    fleet = await connect_fleet(load_mission(mission_path), None, timeout=timeout, require_all=False)
    try:
        async def telemetry(v: Any) -> None:
            with contextlib.suppress(TimeoutError):
                await v.wait_until(lambda v: v.position is not None and v.landed_state is not None,
                                   timeout, "telemetry")

        await asyncio.gather(*(telemetry(v) for v in fleet.vehicles.values()))
        await asyncio.sleep(0.3)
        out: dict[str, Seen] = {}
        for rid in rovers:
            v, p = fleet.vehicles[rid], fleet.vehicles[rid].enu
            deck = None
            for cid in TEAMS:
                c = fleet.vehicles[cid].enu
                if v.on_ground and p is not None and c is not None and \
                        math.hypot(p[0] - c[0], p[1] - c[1]) <= DECK:
                    deck = cid
            out[rid] = Seen(p, v.on_ground, deck)
        return out
    finally:
        await fleet.close()


def describe(seen: dict[str, Seen]) -> str:
    return "\n".join(f"  {rid}: enu={tuple(round(c, 1) for c in s.enu) if s.enu else None} "
                     f"on_ground={s.on_ground} deck={s.deck}" for rid, s in seen.items())


# ---------------------------------------------------------------------------------------------------
# the kill moments
# ---------------------------------------------------------------------------------------------------

def _planned_not_launched(js: dict[str, Records]) -> bool:
    return bool(of_kind(team_records(js, "deploy"), "plan"))


def _check_before_first_launch(js: dict[str, Records]) -> None:
    dep = team_records(js, "deploy")
    assert of_kind(dep, "plan"), "killed before a team's plan"
    assert not of_kind(dep, "launch"), "the kill came after a team's first launch record (test timing)"


def _launched(js: dict[str, Records]) -> bool:
    return bool(of_kind(team_records(js, "deploy"), "rover_launched"))


def _check_mid_deployment(js: dict[str, Records]) -> None:
    dep = team_records(js, "deploy")
    launched = {r["vehicle"] for r in of_kind(dep, "rover_launched")}
    assert 1 <= len(launched) < len(ROVERS), f"{sorted(launched)} launched when killed (test timing)"


def _launch_at_stop_2(js: dict[str, Records]) -> bool:
    return any(r.get("kind") == "launch" and r.get("stop") == 2 for r in team_records(js, "deploy"))


def _check_launch_written(js: dict[str, Records]) -> None:
    dep = team_records(js, "deploy")
    assert _launch_at_stop_2(js)
    reached = {r["task"] for r in of_kind(dep, "task_reached")}
    assert len(reached) < len(TASKS), f"every task reached before the kill (test timing): {reached}"


def _dwelling(js: dict[str, Records]) -> bool:
    return bool(of_kind(js["run"], "dwell"))


def _check_dwelling(js: dict[str, Records]) -> None:
    assert of_kind(js["run"], "dwell")
    assert not [r for r in of_kind(js["run"], "teams_plan") if r.get("phase") == "collect"], \
        "the collection was shared before the kill (test timing)"


def _collecting(js: dict[str, Records]) -> bool:
    col = team_records(js, "collect")
    i = next((k for k, r in enumerate(col) if r.get("kind") == "collection_started"), None)
    return i is not None and bool(of_kind(col[i:], "command"))


def _check_collecting(js: dict[str, Records]) -> None:
    col = team_records(js, "collect")
    assert not of_kind(js["run"], "summary"), "the run finished before the kill (test timing)"
    loaded = {r["vehicle"] for r in of_kind(col, "rover_loaded")}
    assert len(loaded) < len(ROVERS), f"every rover loaded before the kill (test timing): {loaded}"


@dataclass(frozen=True)
class KillCase:
    command: list[str]
    until: Callable[[dict[str, Records]], bool]
    what: str
    check_killed: Callable[[dict[str, Records]], None]


KILL_CASES = {
    "deploy-before-first-launch": KillCase(["deploy"], _planned_not_launched, "a team's plan record",
                                           _check_before_first_launch),
    "deploy-mid-deployment": KillCase(["deploy"], _launched, "a team's rover_launched record",
                                      _check_mid_deployment),
    "deploy-launch-written-ahead": KillCase(["deploy"], _launch_at_stop_2, "a launch record at a stop 2",
                                            _check_launch_written),
    "run-mid-deployment": KillCase(["run", "--dwell", "1"], _launched, "a team's rover_launched record",
                                   _check_mid_deployment),
    "run-during-dwell": KillCase(["run", "--dwell", "4"], _dwelling, "the run's dwell record",
                                 _check_dwelling),
    "run-during-collection": KillCase(["run", "--dwell", "1"], _collecting,
                                      "a command after a team's collection_started", _check_collecting),
}


@pytest.mark.parametrize("case", list(KILL_CASES))
def test_kill_9_a_two_team_run_then_resume_finishes_it(tmp_path: Path, case: str) -> None:
    kc = KILL_CASES[case]
    mission, d = write_two_teams(tmp_path)
    run_dir = tmp_path / "run"
    with sim_process(mission, tmp_path / "sim.log", speedup=5.0, vehicles=len(TEAMS) + len(ROVERS)) as sim:
        with controller([*kc.command, "--mission", str(mission), "--run-dir", str(run_dir), "--headless",
                         "--yes"], tmp_path / "fly.log") as fly:
            wait_journals(fly, run_dir, kc.until, kc.what)
            rc = fly.kill9()
            out = fly.output()
        assert rc == -signal.SIGKILL
        assert first_output_line_names(out, run_dir), out[:500]
        killed = journals(run_dir)
        kc.check_killed(killed)
        before = journal_texts(run_dir)
        rc, out = run_ctl(["resume", "--run", str(run_dir), "--headless", "--yes"], tmp_path / "resume.log")
        seen = observe(mission)
        assert sim.proc.poll() is None, sim.output()
    p = Problems()
    context = check_resumed(p, rc, out, run_dir, before, seen, d, run=kc.command[0] == "run")
    p.assert_none(*context)


def test_a_resume_killed_in_turn_is_resumed_again(tmp_path: Path) -> None:
    """A two-team deploy killed after a launch, its resume killed as soon as it has taken over
    (its ``resumed`` record), and a second resume finishes it: still no task or rover flown twice."""
    mission, d = write_two_teams(tmp_path)
    run_dir = tmp_path / "run"
    args = ["--run", str(run_dir), "--headless", "--yes"]
    with sim_process(mission, tmp_path / "sim.log", speedup=5.0, vehicles=len(TEAMS) + len(ROVERS)) as sim:
        with controller(["deploy", "--mission", str(mission), "--run-dir", str(run_dir), "--headless",
                         "--yes"], tmp_path / "fly.log") as fly:
            wait_journals(fly, run_dir, _launched, "a team's rover_launched record")
            assert fly.kill9() == -signal.SIGKILL
        _check_mid_deployment(journals(run_dir))
        before = journal_texts(run_dir)
        with controller(["resume", *args], tmp_path / "resume1.log") as again:
            wait_journals(again, run_dir, lambda js: bool(of_kind(js["run"], "resumed")),
                          "the resumed record")
            assert again.kill9() == -signal.SIGKILL
        rc, out = run_ctl(["resume", *args], tmp_path / "resume2.log")
        seen = observe(mission)
        assert sim.proc.poll() is None, sim.output()
    p = Problems()
    p.assert_none(*check_resumed(p, rc, out, run_dir, before, seen, d, run=False, resumes=2))


def check_resumed(p: Problems, rc: int, out: str, run_dir: Path, before: dict[str, str],
                  seen: dict[str, Seen], d: dict[str, Any], run: bool, resumes: int = 1) -> list[str]:
    p.check(rc == 0, f"resume exited {rc} (want 0)")
    p.check("Traceback" not in out, "a traceback in the output of resume")
    after = journal_texts(run_dir)
    for name, text in before.items():  # appended to, never rewritten; every line whole
        whole = text[: text.rfind("\n") + 1]
        p.check(after.get(name, "").startswith(whole), f"resume rewrote {name}")
    run_recs = parse_journal_strict(run_dir)
    resumed = of_kind(run_recs[len(before["journal.jsonl"].splitlines()):], "resumed")
    p.check(len(resumed) == resumes,
            f"{len(resumed)} 'resumed' records appended to the run's journal (want {resumes})")
    js = journals(run_dir)
    dep = team_records(js, "deploy")
    launched = Counter(r["vehicle"] for r in of_kind(dep, "rover_launched"))
    p.check(all(n == 1 for n in launched.values()), f"a rover launched twice: {dict(launched)}")
    reached = Counter(r["task"] for r in of_kind(dep, "task_reached"))
    p.check(all(n == 1 for n in reached.values()), f"a task reached twice: {dict(reached)}")
    p.check(set(reached) == set(TASKS), f"tasks reached {sorted(reached)} (want {TASKS})")
    for key, recs in js.items():
        for v in launch_violations(recs) if key.endswith("/deploy") else ():
            p.check(False, f"{key}: {v}")
    # the rover each task was flown by (its rover_launched record, else its last launch record)
    flown = {r["task"]: r["vehicle"] for r in of_kind(dep, "launch")}
    flown |= {r["task"]: r["vehicle"] for r in of_kind(dep, "rover_launched")}
    summary = read_summary(run_dir)
    p.check(summary.get("result") == "complete", f"summary result {summary.get('result')!r}")
    p.check(sorted(summary.get("tasks_reached", [])) == TASKS,
            f"summary tasks_reached {summary.get('tasks_reached')}")
    positions = {t["id"]: tuple(t["position"]) for t in d["tasks"]}
    if run:
        loaded = Counter(r["vehicle"] for r in of_kind(team_records(js, "collect"), "rover_loaded"))
        p.check(all(n == 1 for n in loaded.values()), f"a rover loaded twice: {dict(loaded)}")
        p.check(set(summary.get("rovers_loaded", [])) >= set(flown.values()),
                f"summary rovers_loaded {summary.get('rovers_loaded')} (flown {flown})")
        off = [rid for rid, s in seen.items() if s.deck is None]
        p.check(not off, f"the world: rovers not on a carrier's deck: {off}")
    else:
        on_task = {t: [rid for rid, s in seen.items() if s.enu is not None and math.dist(s.enu, pos) <= REACH]
                   for t, pos in positions.items()}
        p.check(all(len(v) == 1 for v in on_task.values()), f"the world: rovers on each task {on_task}")
        p.check({t: v[0] for t, v in on_task.items() if len(v) == 1} == flown,
                f"the world's rover on each task {on_task} is not the journals' {flown}")
        p.check(set(summary.get("rovers_airborne") or {}) == set(flown.values()),
                f"summary rovers_airborne {sorted(summary.get('rovers_airborne') or {})} (flown {flown})")
    told = ("resumed", "launch", "rover_launched", "task_reached", "rover_loaded", "team", "teams_plan",
            "handover", "dwell", "summary")
    story = [f"  {k}: " + " ".join(f"{r['kind']}:{r.get('vehicle') or r.get('task') or r.get('team') or ''}"
                                   for r in recs if r["kind"] in told)
             for k, recs in js.items()]
    return ["journals after resume:", *story, f"the world after resume:\n{describe(seen)}",
            f"resume output:\n{out[-2000:]}"]


SIX_ROVERS = ["r1", "r2", "r3", "r4", "r5", "r6"]  # c2 with 4 rovers


@dataclass
class FaultResume:
    """A two-team deployment flown with a simulated fault, killed (-9) once ``until`` held, then
    resumed: what the journals held when killed, the resume's exit code and output."""

    d: dict[str, Any]
    run_dir: Path
    killed: dict[str, Records]
    before: dict[str, str]
    rc: int
    out: str
    seen: dict[str, Seen]


def _fault_kill_resume(tmp_path: Path, fault: dict[str, Any], until: Callable[[dict[str, Records]], bool],
                       what: str) -> FaultResume:
    mission, d = write_two_teams(tmp_path)
    d["carriers"][1]["fleet"] = {"count": 4, "sysid_start": 31}
    d["sim"]["faults"] = [fault]
    mission.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
    run_dir = tmp_path / "run"
    with sim_process(mission, tmp_path / "sim.log", speedup=5.0, vehicles=2 + len(SIX_ROVERS)) as sim:
        with controller(["deploy", "--mission", str(mission), "--run-dir", str(run_dir), "--headless",
                         "--yes"], tmp_path / "fly.log") as fly:
            wait_journals(fly, run_dir, until, what)
            assert fly.kill9() == -signal.SIGKILL
        killed, before = journals(run_dir), journal_texts(run_dir)
        rc, out = run_ctl(["resume", "--run", str(run_dir), "--headless", "--yes"], tmp_path / "resume.log")
        seen = observe(mission, rovers=SIX_ROVERS)
        assert sim.proc.poll() is None, sim.output()
    return FaultResume(d, run_dir, killed, before, rc, out, seen)


def _check_resume_ran(p: Problems, r: FaultResume) -> dict[str, Records]:
    """The resume exited 0 without a traceback; the journals after it."""
    p.check(r.rc == 0, f"resume exited {r.rc}")
    p.check("Traceback" not in r.out, "a traceback in the output of resume")
    return journals(r.run_dir)


def test_kill_9_after_a_handover_then_resume_honours_it(tmp_path: Path) -> None:
    """c1's r1 refuses to arm (a simulated fault) and c1 has no spare: c1 hands its unserved task
    over to c2 (4 rovers). The controller is killed right after the ``handover`` record; resumed,
    the task is c2's: c2 flies it once, c1 never does."""

    def handed(js: dict[str, Records]) -> bool:
        return any(r.get("to_team") == "c2" for r in of_kind(js["run"], "handover"))

    r = _fault_kill_resume(tmp_path, {"kind": "refuse_arm", "vehicle": "r1"}, handed,
                           "a handover record to c2")
    (h,) = [x for x in of_kind(r.killed["run"], "handover") if x.get("to_team") == "c2"]
    task = h["tasks"][0]
    assert task not in {x["task"] for x in of_kind(team_records(r.killed, "deploy"), "task_reached")}
    p = Problems()
    js = _check_resume_ran(p, r)
    after = journal_texts(r.run_dir)
    for name, text in r.before.items():
        p.check(after.get(name, "").startswith(text[: text.rfind("\n") + 1]), f"resume rewrote {name}")
    reached = Counter(x["task"] for x in of_kind(team_records(js, "deploy"), "task_reached"))
    p.check(reached == Counter({t: 1 for t in TASKS}), f"tasks reached {dict(reached)} (each once)")
    by_c2 = {x["task"] for x in of_kind(js.get("c2/deploy", []), "task_reached")}
    by_c1 = {x["task"] for x in of_kind(js.get("c1/deploy", []), "task_reached")}
    p.check(task in by_c2 and task not in by_c1, f"handed {task}: reached by c1 {by_c1}, c2 {by_c2}")
    c1_launches = {x["task"] for x in of_kind(js.get("c1/deploy", []), "rover_launched")}
    p.check(task not in c1_launches, f"c1 launched a rover for {task}, handed to c2")
    launched = Counter(x["vehicle"] for x in of_kind(team_records(js, "deploy"), "rover_launched"))
    p.check(all(n == 1 for n in launched.values()) and "r1" not in launched,
            f"rovers launched {dict(launched)}")
    summary = read_summary(r.run_dir)
    p.check(summary.get("result") == "complete", f"summary result {summary.get('result')}")
    p.check(any(x["tasks"] == [task] and x["to"] == "c2" for x in summary.get("handovers", [])),
            f"summary handovers {summary.get('handovers')}")
    on_task = _on_tasks(r.seen, r.d)
    p.check(all(len(v) == 1 for v in on_task.values()), f"the world: rovers on each task {on_task}")
    p.assert_none(f"the world:\n{describe(r.seen)}", f"resume output:\n{r.out[-2000:]}")


def test_kill_9_after_a_carrier_failed_preflight_then_resume_leaves_its_team_over(tmp_path: Path) -> None:
    """c1's carrier reports no GPS (a simulated fault): its preflight fails, its deployment run ends
    and its tasks go to c2 (4 rovers). The controller is killed once c1's run has ended; resumed,
    c1 is not flown again (its journal untouched, no second preflight) and c2 flies every task once."""

    def c1_over(js: dict[str, Records]) -> bool:
        return any(x.get("team") == "c1" and x.get("status") == "ended" for x in of_kind(js["run"], "team"))

    r = _fault_kill_resume(tmp_path, {"kind": "no_gps", "vehicle": "c1"}, c1_over,
                           "c1's deployment run ended")
    p = Problems()
    js = _check_resume_ran(p, r)
    after = journal_texts(r.run_dir)
    c1_journal = next(name for name in r.before if "c1" in name and "deploy" in name)
    p.check(after[c1_journal] == r.before[c1_journal], "resume flew c1 again (its deployment journal grew)")
    (resumed,) = of_kind(js["run"], "resumed")
    p.check(set(resumed.get("deploy_ended", {})) == {"c1"}, f"resumed record {resumed}")
    reached = Counter(x["task"] for x in of_kind(team_records(js, "deploy"), "task_reached"))
    p.check(reached == Counter({t: 1 for t in TASKS}), f"tasks reached {dict(reached)} (each once)")
    by_c1 = {x["task"] for x in of_kind(js.get("c1/deploy", []), "task_reached")}
    p.check(not by_c1, f"c1 reached {by_c1}")
    summary = read_summary(r.run_dir)
    p.check(summary.get("result") == "complete", f"summary result {summary.get('result')}")
    p.assert_none(f"resume output:\n{r.out[-2000:]}")


# ---------------------------------------------------------------------------------------------------
# what resume refuses, in one line
# ---------------------------------------------------------------------------------------------------

def _teams_run_folder(tmp_path: Path, d: dict[str, Any], teams: dict[str, list[str]] | None) -> Path:
    """A run folder of a several-team deploy killed right after its ``run`` record."""
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / "mission.yaml").write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
    rec = {"kind": "run", "t": time.time(), "elapsed": 0.0, "mission": d["name"], "command": "deploy",
           "file": "", "sim": False, "speedup": 1.0, "planner": None, "dwell": None}
    if teams is not None:
        rec["teams"] = teams
    (run_dir / "journal.jsonl").write_text(json.dumps(rec) + "\n", encoding="utf-8")
    return run_dir


@pytest.mark.parametrize(("change", "teams", "message"), [
    ("sim", TEAMS, "embedded simulated fleet"),
    ("udp", {"c1": ["r1", "r2"], "c9": ["r3", "r4"]}, "are not the mission's carriers"),
    ("udp", None, "names neither its teams"),
], ids=["embedded-sim", "other-teams", "no-teams-named"])
def test_resume_of_a_teams_run_refuses_in_one_line(tmp_path: Path, change: str,
                                                   teams: dict[str, list[str]] | None, message: str) -> None:
    d = two_teams()
    if change == "udp":
        for c in d["carriers"]:
            c["connection"] = f"udp://127.0.0.1:{free_udp_port()}"
    run_dir = _teams_run_folder(tmp_path, d, teams)
    rc, out = run_ctl(["resume", "--run", str(run_dir), "--headless", "--yes"], tmp_path / "resume.log",
                      timeout=60.0)
    assert rc == 2, out
    assert "Traceback" not in out, out
    assert message in out, out
    assert len([line for line in out.splitlines() if line.strip()]) == 1, out


# ---------------------------------------------------------------------------------------------------
# a --team controller resumed
# ---------------------------------------------------------------------------------------------------

def _records(run_dir: Path) -> Records:
    return _partial(run_dir / "journal.jsonl")


def _team_launched(run_dir: Path) -> Callable[[dict[str, Records]], bool]:
    return lambda _js: bool(of_kind(_records(run_dir), "rover_launched"))


def _wait_records(ctl: Any, run_dir: Path, until: Callable[[Records], bool], what: str) -> Records:
    wait_journals(ctl, run_dir, lambda _js: until(_records(run_dir)), what)
    return _records(run_dir)



def check_team_controller_resumed(p: Problems, codes: tuple[int, int], out: str, dirs: tuple[Path, Path],
                                  killed: Records) -> tuple[Records, Records, Records]:
    """What a ``--team c1`` controller killed and resumed beside a running c2 must show: both exit 0
    without a traceback, one ``resumed`` record after the kill, c1's link under a new session beside
    the killed one, every task reached once by the two teams, no launch rule broken. Returns c1's and
    c2's journals and c1's records after the kill."""
    rc, rc2 = codes
    p.check(rc == 0 and rc2 == 0, f"resume of c1 exited {rc}, c2 exited {rc2}")
    p.check("Traceback" not in out, "a traceback in the output of resume")
    r1, r2 = parse_journal_strict(dirs[0]), parse_journal_strict(dirs[1])
    after = r1[len(killed):]
    p.check(len(of_kind(after, "resumed")) == 1, "no single 'resumed' record appended to c1's journal")
    sessions = {r.get("session") for r in of_kind(r1, "team") if r.get("session")}
    p.check(len(sessions) == 2, f"c1's link sessions {sessions}: want the killed one and a new one")
    reached = Counter(r["task"] for r in of_kind(r1 + r2, "task_reached"))
    p.check(reached == Counter(dict.fromkeys(TASKS, 1)), f"tasks reached (both teams) {dict(reached)}")
    for v in launch_violations(r1) + launch_violations(r2):
        p.check(False, v)
    return r1, r2, after

def _check_team_killed(recs: Records, rovers: list[str]) -> None:
    launched = {r["vehicle"] for r in of_kind(recs, "rover_launched")}
    assert 1 <= len(launched) < len(rovers), f"{sorted(launched)} launched when killed (test timing)"


def _on_tasks(seen: dict[str, Seen], d: dict[str, Any]) -> dict[str, list[str]]:
    return {t["id"]: [rid for rid, s in seen.items()
                      if s.enu is not None and math.dist(s.enu, t["position"]) <= REACH]
            for t in d["tasks"]}


def test_kill_9_a_team_controller_then_resume_flies_its_share(tmp_path: Path) -> None:
    """``deploy --team c1`` (no bus: its share alone) killed after its first launch; resumed, it
    flies the rest of c1's share and nothing else: c2's rovers stay on c2's deck."""
    mission, d = write_two_teams(tmp_path)
    run_dir = tmp_path / "c1"
    with sim_process(mission, tmp_path / "sim.log", speedup=5.0, vehicles=len(TEAMS) + len(ROVERS)) as sim:
        with controller(["deploy", "--team", "c1", "--mission", str(mission), "--run-dir", str(run_dir),
                         "--headless", "--yes"], tmp_path / "fly.log") as fly:
            killed = _wait_records(fly, run_dir, lambda rs: bool(of_kind(rs, "rover_launched")),
                                   "c1's rover_launched record")
            assert fly.kill9() == -signal.SIGKILL
        _check_team_killed(killed, TEAMS["c1"])
        assert of_kind(killed, "run")[0].get("team") == "c1", of_kind(killed, "run")
        rc, out = run_ctl(["resume", "--run", str(run_dir), "--headless", "--yes"], tmp_path / "resume.log")
        seen = observe(mission)
        assert sim.proc.poll() is None, sim.output()
    p = Problems()
    p.check(rc == 0, f"resume exited {rc}")
    p.check("Traceback" not in out, "a traceback in the output of resume")
    recs = parse_journal_strict(run_dir)
    p.check(len(of_kind(recs, "resumed")) == 1, "no single 'resumed' record")
    for v in launch_violations(recs):
        p.check(False, v)
    reached = Counter(r["task"] for r in of_kind(recs, "task_reached"))
    p.check(reached == Counter({"t1": 1, "t2": 1}), f"c1 reached {dict(reached)} (want t1, t2 once)")
    launched = Counter(r["vehicle"] for r in of_kind(recs, "rover_launched"))
    p.check(set(launched) <= set(TEAMS["c1"]) and all(n == 1 for n in launched.values()),
            f"rovers launched {dict(launched)}")
    result = read_summary(run_dir).get("result")
    p.check(result == "complete", f"summary result {result}")
    on_task = _on_tasks(seen, d)
    p.check(len(on_task["t1"]) == 1 and len(on_task["t2"]) == 1 and not on_task["t3"] and not on_task["t4"],
            f"the world: rovers on the tasks {on_task}")
    p.check(all(seen[r].deck == "c2" for r in TEAMS["c2"]), "the world: c2's rovers left its deck")
    p.assert_none(f"the world:\n{describe(seen)}", f"resume output:\n{out[-2000:]}")


def test_kill_9_a_team_collection_then_resume_collects_its_deck(tmp_path: Path) -> None:
    """``deploy --team c1`` to the end, then ``collect --team c1`` killed once its collection has
    started: resumed, c1 collects its own rovers (each loaded once), c2's stay on its deck."""
    mission, _ = write_two_teams(tmp_path)
    dep, col = tmp_path / "c1-deploy", tmp_path / "c1-collect"
    team = ["--team", "c1", "--mission", str(mission), "--headless", "--yes"]
    with sim_process(mission, tmp_path / "sim.log", speedup=5.0, vehicles=len(TEAMS) + len(ROVERS)) as sim:
        rc, out = run_ctl(["deploy", *team, "--run-dir", str(dep)], tmp_path / "deploy.log")
        assert rc == 0, out
        with controller(["collect", *team, "--run-dir", str(col)], tmp_path / "collect.log") as fly:
            killed = _wait_records(fly, col, lambda rs: bool(of_kind(rs, "collection_started")),
                                   "c1's collection_started record")
            assert fly.kill9() == -signal.SIGKILL
        assert of_kind(killed, "run")[0].get("team") == "c1"
        rc, out = run_ctl(["resume", "--run", str(col), "--headless", "--yes"], tmp_path / "resume.log")
        seen = observe(mission)
        assert sim.proc.poll() is None, sim.output()
    p = Problems()
    p.check(rc == 0, f"resume exited {rc}")
    p.check("Traceback" not in out, "a traceback in the output of resume")
    recs = parse_journal_strict(col)
    p.check(len(of_kind(recs, "resumed")) == 1, "no single 'resumed' record")
    loaded = Counter(r["vehicle"] for r in of_kind(recs, "rover_loaded"))
    p.check(loaded == Counter({"r1": 1, "r2": 1}), f"rovers loaded {dict(loaded)} (want c1's r1, r2 once)")
    p.check(read_summary(col).get("result") == "complete", f"summary {read_summary(col).get('result')}")
    decks = {rid: s.deck for rid, s in seen.items()}
    p.check(decks == {"r1": "c1", "r2": "c1", "r3": "c2", "r4": "c2"}, f"the world: decks {decks}")
    p.assert_none(f"the world:\n{describe(seen)}", f"resume output:\n{out[-2000:]}")


@pytest.mark.skipif(MOSQUITTO is None, reason="mosquitto binary not installed")
def test_a_resumed_team_controller_rejoins_the_bus(tmp_path: Path) -> None:
    """Both teams' controllers (``deploy --team``) coordinate over a real mosquitto; c1's is killed
    after its first launch and resumed while c2 flies on: c1 re-joins the bus (a new session, its
    share claimed again) and finishes its share; every task is reached once, by one team."""
    broker = Broker(tmp_path)
    broker.start()
    try:
        mission, d = write_two_teams(tmp_path, links=2)  # each controller on its own team's link
        d["mqtt"] = {"url": broker.url, "topic_prefix": "test/resume-team"}
        mission.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
        d1, d2 = tmp_path / "c1", tmp_path / "c2"
        vehicles = len(TEAMS) + len(ROVERS)
        with sim_process(mission, tmp_path / "sim.log", speedup=5.0, vehicles=vehicles) as sim, \
                controller(["deploy", "--team", "c2", "--mission", str(mission), "--run-dir", str(d2),
                            "--headless", "--yes"], tmp_path / "c2.log") as c2:
            with controller(["deploy", "--team", "c1", "--mission", str(mission), "--run-dir", str(d1),
                             "--headless", "--yes"], tmp_path / "c1.log") as c1:
                killed = _wait_records(c1, d1, lambda rs: bool(of_kind(rs, "rover_launched")),
                                       "c1's rover_launched record")
                assert c1.kill9() == -signal.SIGKILL
            _check_team_killed(killed, TEAMS["c1"])
            rc, out = run_ctl(["resume", "--run", str(d1), "--headless", "--yes"], tmp_path / "resume.log")
            rc2 = c2.wait()
            seen = observe(mission)
            assert sim.proc.poll() is None, sim.output()
    finally:
        broker.stop()
    p = Problems()
    r1, r2, after = check_team_controller_resumed(p, (rc, rc2), out, (d1, d2), killed)
    rejoined = [r for r in of_kind(after, "team") if r.get("session")]
    p.check(bool(rejoined) and rejoined[0].get("share") == ["t1", "t2"], f"c1 re-joined with {rejoined}")
    launched = Counter(r["vehicle"] for r in of_kind(r1 + r2, "rover_launched"))
    p.check(all(n == 1 for n in launched.values()), f"a rover launched twice: {dict(launched)}")
    on_task = _on_tasks(seen, d)
    p.check(all(len(v) == 1 for v in on_task.values()), f"the world: rovers on each task {on_task}")
    p.assert_none(f"the world:\n{describe(seen)}", f"resume output:\n{out[-2000:]}")
