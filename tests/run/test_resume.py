"""``fleetctl resume``: finishing a run whose controller was killed, and the records of an
interrupted one.

Each test serves a small mission's simulated fleet with ``fleetctl sim`` in its own process (so
the fleet outlives the controller, as a real one does) and runs the controller as a subprocess
against it with ``--run-dir`` (and ``--yes``: its URLs are real, there is no terminal to confirm
arming on). The journal is written ahead (fsynced before each command), so the
tests poll it to pick the moment to kill the controller:

* the kill matrix: ``kill -9`` of ``fleetctl deploy`` before the first launch, after the first
  launch, with the carrier held at a stop, in the write-ahead window of a launch, and of
  ``fleetctl run`` during collection; then ``fleetctl resume --run DIR --headless`` must finish
  the run: no rover launched twice or for a second task while it flies, no task reached twice,
  every task reached (every launched rover loaded for ``run``), the journal appended to (a
  ``resumed`` record) and ``summary.json`` accounting for the whole run - and the simulated world
  (seen through a fresh MAVLink connection) agrees: one rover on each task, the spare on the deck;
  or everyone back on the deck;
* SIGTERM (exit 143) and Ctrl-C (exit 130) mid-deploy: airborne rovers told to hold, a summary
  that is true (tasks reached = the journal's ``task_reached`` records, launched rovers never
  "on deck", airborne rovers listed with position/state/task), checked against the world too;
* resume refusing what it cannot finish: another mission file than the saved copy, a folder
  without journal, a run on the embedded simulator (``connection: sim``).

The mission (:func:`resume_helpers.resume_mission_dict`): 4 tasks in a zig-zag east of the
carrier, 5 rovers (one spare), 4 stops with one rover each; the sim runs at 5x and the
controller's mission clock is the wall clock.
"""

from __future__ import annotations

import json
import signal
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml

from tests.run.ctl_helpers import mission_dict, write_mission
from tests.run.resume_helpers import (
    ROVERS,
    TASKS,
    Problems,
    Records,
    Seen,
    airborne,
    controller,
    describe,
    first_output_line_names,
    journal_lines,
    kinds_summary,
    launch_violations,
    observe_fleet,
    of_kind,
    on_deck,
    parse_journal_strict,
    read_summary,
    rovers_launched,
    rovers_on_tasks,
    run_ctl,
    sim_process,
    task_positions,
    tasks_reached,
    wait_journal,
    write_resume_mission,
)

pytestmark = pytest.mark.slow

# ---------------------------------------------------------------------------------------------------
# the kill matrix
# ---------------------------------------------------------------------------------------------------


def _index(recs: Records, pred: Callable[[dict], bool]) -> int | None:
    return next((i for i, r in enumerate(recs) if pred(r)), None)


def _collect_commanded(recs: Records) -> bool:
    """A ``phase`` collect record, and a ``command`` record after it."""
    i = _index(recs, lambda r: r.get("kind") == "phase" and r.get("phase") == "collect")
    return i is not None and any(r.get("kind") == "command" for r in recs[i + 1:])


def _held_at_stop_2(recs: Records) -> bool:
    return any(r.get("kind") == "stop_reached" and r.get("stop") == 2 for r in recs)


def _launch_at_stop_3(recs: Records) -> bool:
    return any(r.get("kind") == "launch" and r.get("stop") == 3 for r in recs)


def _check_before_first_launch(recs: Records) -> None:
    assert of_kind(recs, "plan"), "killed before the plan"
    assert not of_kind(recs, "launch"), "the kill came after the first launch record (test timing)"


def _check_after_first_launch(recs: Records) -> None:
    n = len(rovers_launched(recs))
    assert 1 <= n < len(TASKS), f"{n} rovers launched when killed (test timing)"


def _check_held_at_stop(recs: Records) -> None:
    assert _held_at_stop_2(recs)
    assert not any(r.get("kind") == "carrier_released" and r.get("stop") == 2 for r in recs), \
        "the carrier was released from stop 2 before the kill (test timing)"


def _check_launch_written(recs: Records) -> None:
    assert _launch_at_stop_3(recs)
    assert len(tasks_reached(recs)) < len(TASKS)


def _check_during_collection(recs: Records) -> None:
    assert _collect_commanded(recs)
    assert not of_kind(recs, "summary", "collected"), "the run finished before the kill (test timing)"
    launched = set(rovers_launched(recs))
    loaded = {r["vehicle"] for r in of_kind(recs, "rover_loaded")}
    assert loaded < launched, f"killed with {sorted(loaded)} of {sorted(launched)} loaded (test timing)"


@dataclass(frozen=True)
class KillCase:
    command: list[str]  # after "fleetctl"; --mission/--run-dir/--headless/--yes are added
    until: Callable[[Records], bool]
    what: str
    check_killed: Callable[[Records], None]


KILL_CASES = {
    "a-before-first-launch": KillCase(["deploy"], lambda rs: bool(of_kind(rs, "plan")), "a plan record",
                                      _check_before_first_launch),
    "b-after-first-launch": KillCase(["deploy"], lambda rs: bool(of_kind(rs, "rover_launched")),
                                     "a rover_launched record", _check_after_first_launch),
    "c-carrier-held-at-stop": KillCase(["deploy"], _held_at_stop_2, "stop_reached for stop 2",
                                       _check_held_at_stop),
    "e-launch-written-ahead": KillCase(["deploy"], _launch_at_stop_3, "the launch record of stop 3",
                                     _check_launch_written),
    "d-run-during-collection": KillCase(["run", "--dwell", "1"], _collect_commanded,
                                        "a command record after the collect phase record",
                                        _check_during_collection),
}


@pytest.mark.parametrize("case", list(KILL_CASES))
def test_kill_9_then_resume_finishes_the_run(tmp_path: Path, case: str) -> None:
    kc = KILL_CASES[case]
    mission, d = write_resume_mission(tmp_path)
    run_dir = tmp_path / "run"
    with sim_process(mission, tmp_path / "sim.log") as sim:
        # -- fly and kill -9 at the moment ------------------------------------------------------
        with controller([*kc.command, "--mission", str(mission), "--run-dir", str(run_dir), "--headless",
                         "--yes"], tmp_path / "fly.log") as fly:
            wait_journal(fly, run_dir, kc.until, kc.what)
            rc = fly.kill9()
            out = fly.output()
        assert rc == -signal.SIGKILL
        assert first_output_line_names(out, run_dir), out[:500]
        killed_lines = journal_lines(run_dir)
        killed = parse_journal_strict(run_dir)  # every line whole: written ahead, one write per record
        assert killed[0]["kind"] == "run", killed[0]
        kc.check_killed(killed)
        assert not launch_violations(killed), launch_violations(killed)
        assert (run_dir / "mission.yaml").exists()

        # -- resume -----------------------------------------------------------------------------
        summary_out = tmp_path / "resume-summary.json"
        rc, out = run_ctl(["resume", "--run", str(run_dir), "--headless", "--yes", "--summary",
                           str(summary_out)], tmp_path / "resume.log")
        seen = observe_fleet(mission)
        assert sim.proc.poll() is None, sim.output()

    p = Problems()
    p.check(summary_out.exists() and read_json(summary_out) == read_summary(run_dir),
            f"resume --summary {summary_out.name} is missing or differs from summary.json")
    p.assert_none(*check_resumed(p, rc, out, run_dir, killed_lines, seen, d, run=kc.command[0] == "run"))


def task_rovers(recs: Records) -> dict[str, str]:
    """rover -> task: of the ``rover_launched`` records, and for a task without one the rover of
    its last ``launch`` record (a rover resume found flying or on the task after a kill in the
    write-ahead window between the two)."""
    out = rovers_launched(recs)
    flown = set(out.values())
    last_launch = {r["task"]: r["vehicle"] for r in of_kind(recs, "launch")}
    for task, rid in last_launch.items():
        if task not in flown and rid not in out:
            out[rid] = task
    return out


SUMMARY_KEYS = ("result", "tasks_reached", "tasks_unserved", "rovers_on_deck", "rovers_airborne",
                "rovers_loaded", "error")


def read_json(path: Path) -> dict:
    return json.loads(path.read_text(encoding="utf-8"))


def check_resumed(p: Problems, rc: int, out: str, run_dir: Path, killed_lines: list[str],
                  seen: dict[str, Seen], d: dict, run: bool) -> list[str]:
    """What the records and the world must show after ``fleetctl resume`` finished a run of the
    test mission: the problems go to ``p``; returns what to show with them."""
    p.check(rc == 0, f"resume exited {rc} (want 0)")
    p.check("Traceback" not in out, "a traceback in the output of resume")
    recs = parse_journal_strict(run_dir)
    story = kinds_summary(recs)
    # appended to, not rewritten, with one 'resumed' record saying what it found
    p.check(journal_lines(run_dir)[:len(killed_lines)] == killed_lines,
            "resume rewrote the records of the interrupted run")
    resumed = of_kind(recs[len(killed_lines):], "resumed")
    p.check(len(resumed) == 1, f"{len(resumed)} 'resumed' records appended (want 1)")
    p.check(not resumed or set(resumed[0]) - {"t", "elapsed", "kind"}, "the resumed record says nothing")
    # never a rover launched twice or for a second task while it flew, never a task reached twice
    for v in launch_violations(recs):
        p.check(False, v)
    reached = tasks_reached(recs)
    p.check(reached == set(TASKS), f"tasks with a task_reached record: {sorted(reached)} (want all {TASKS})")
    launched = task_rovers(recs)
    p.check(sorted(launched.values()) == TASKS and len(launched) == len(TASKS),
            f"rover -> task launched (rover_launched, else the task's last launch record): {launched} "
            "(want one rover for each task)")
    summary = read_summary(run_dir)
    s_reached = summary.get("tasks_reached", [])
    p.check(summary.get("result") == "complete", f"summary result {summary.get('result')!r} (want complete)")
    p.check(sorted(s_reached) == TASKS, f"summary tasks_reached {s_reached} (want all {TASKS})")
    p.check(set(s_reached) == reached, f"summary tasks_reached {sorted(s_reached)} != tasks with a "
            f"task_reached record {sorted(reached)}")
    p.check(not summary.get("tasks_unserved"), f"summary tasks_unserved {summary.get('tasks_unserved')}")
    if run:  # every launched rover loaded, once, and back on the deck
        loaded = Counter(r["vehicle"] for r in of_kind(recs, "rover_loaded"))
        p.check(set(loaded) >= set(launched),
                f"rover_loaded records {dict(loaded)}, launched {sorted(launched)}")
        p.check(not loaded or max(loaded.values()) == 1, f"a rover loaded twice: {dict(loaded)}")
        p.check(set(summary.get("rovers_loaded", [])) >= set(launched),
                f"summary rovers_loaded {summary.get('rovers_loaded')} (launched {sorted(launched)})")
        p.check(on_deck(seen) == set(ROVERS), "the world: not every rover is back on the deck")
    else:  # one rover on each task, the spare on the deck, as the records say
        p.check(not set(summary.get("rovers_on_deck", [])) & set(launched),
                f"summary rovers_on_deck {summary.get('rovers_on_deck')} lists launched rovers")
        p.check(set(summary.get("rovers_airborne", [])) == set(launched),
                f"summary rovers_airborne {summary.get('rovers_airborne')} (launched {sorted(launched)})")
        p.check(set(summary.get("rovers_on_deck", [])) == on_deck(seen),
                f"summary rovers_on_deck {summary.get('rovers_on_deck')} != the world's rovers on the deck "
                f"{sorted(on_deck(seen))}")
        on_tasks = rovers_on_tasks(seen, task_positions(d))
        p.check(all(len(v) == 1 for v in on_tasks.values()), f"the world: rovers on each task {on_tasks}")
        flying = airborne(seen)
        p.check(len(flying) == len(TASKS), f"the world: {len(flying)} rovers in the air {sorted(flying)} "
                f"for {len(TASKS)} tasks")
        p.check(len(on_deck(seen)) == len(ROVERS) - len(TASKS),
                f"the world: on the deck {sorted(on_deck(seen))}")
        there = {t: v[0] for t, v in on_tasks.items() if len(v) == 1}
        p.check(not launched or there == {t: r for r, t in launched.items()},
                f"the world's rover on each task {on_tasks} is not the journal's {launched}")
    return [f"summary after resume: { {k: summary.get(k) for k in SUMMARY_KEYS} }",
            f"journal after resume:\n{story}", f"the world after resume:\n{describe(seen)}",
            f"resume output:\n{out[-1500:]}"]


# ---------------------------------------------------------------------------------------------------
# SIGTERM and Ctrl-C: the records of an interrupted deploy are true
# ---------------------------------------------------------------------------------------------------


def check_interrupted(p: Problems, out: str, recs: Records, summary: dict, seen: dict[str, Seen],
                      run_dir: Path) -> list[str]:
    """The records of a deploy interrupted by a signal are true (problems to ``p``; returns
    what to show with them)."""
    story = kinds_summary(recs)
    p.check("Traceback" not in out, "a traceback in the output")
    p.check(first_output_line_names(out, run_dir), f"first output line {out.splitlines()[:1]} does not name "
            "the run folder")
    p.check(of_kind(recs, "interrupted"), "no 'interrupted' record")
    p.check(summary.get("result") != "complete", "summary result 'complete' after an interruption")
    # tasks reached: exactly those with a task_reached record
    reached = tasks_reached(recs)
    p.check(set(summary.get("tasks_reached", [])) == reached,
            f"summary tasks_reached {sorted(summary.get('tasks_reached', []))} != tasks with a task_reached "
            f"record {sorted(reached)}")
    launched = rovers_launched(recs)
    # a launched rover is never "on deck"; every one of them (none landed again) is airborne
    p.check(not set(summary.get("rovers_on_deck", [])) & set(launched),
            f"summary rovers_on_deck {summary.get('rovers_on_deck')} lists launched rovers "
            f"{sorted(launched)}")
    air = summary.get("rovers_airborne")
    if p.check(isinstance(air, dict), f"summary rovers_airborne is a {type(air).__name__} {air!r}, want a "
               "dict rover id -> {position, state, task}"):
        for rid, entry in air.items():
            p.check(isinstance(entry, dict) and {"position", "state", "task"} <= set(entry),
                    f"rovers_airborne[{rid}] = {entry!r}: want position, state, task")
            if rid in launched and isinstance(entry, dict):
                p.check(entry.get("task") == launched[rid],
                        f"rovers_airborne[{rid}] task {entry.get('task')!r}, launched for {launched[rid]}")
    air_ids = set(air or [])
    p.check(air_ids >= set(launched), f"summary rovers_airborne {sorted(air_ids)} misses launched rovers "
            f"{sorted(set(launched) - air_ids)}")
    # the airborne rovers were told to hold, after the interruption
    i = _index(recs, lambda r: r.get("kind") == "interrupted") or 0
    held = {r["vehicle"] for r in recs[i:] if r.get("kind") == "command" and r.get("command") == "hold"}
    p.check(air_ids <= held, f"told to hold: {sorted(held)}, airborne: {sorted(air_ids)}")
    # and the world agrees with the summary
    p.check(airborne(seen) == air_ids, f"the world's airborne rovers {sorted(airborne(seen))} != summary "
            f"rovers_airborne {sorted(air_ids)}")
    p.check(on_deck(seen) == set(summary.get("rovers_on_deck", [])),
            f"the world's rovers on the deck {sorted(on_deck(seen))} != summary rovers_on_deck "
            f"{sorted(summary.get('rovers_on_deck', []))}")
    return [f"summary when interrupted: { {k: summary.get(k) for k in SUMMARY_KEYS} }",
            f"journal when interrupted:\n{story}", f"the world when interrupted:\n{describe(seen)}",
            f"output tail when interrupted:\n{out[-1500:]}"]


def _after_second_launch(recs: Records) -> bool:
    return len(of_kind(recs, "rover_launched")) >= 2


@pytest.mark.parametrize(("sig", "status", "until", "what"), [
    # SIGTERM with one rover on its task or nearly, one climbing, the carrier at stop 2
    (signal.SIGTERM, 143, _after_second_launch, "a second rover_launched record"),
    # Ctrl-C right after the write-ahead launch record of stop 3: the rover may be arming, taking
    # off or still on the deck - the summary must say which, as the world shows it
    (signal.SIGINT, 130, _launch_at_stop_3, "the launch record of stop 3"),
], ids=["sigterm-143", "ctrl-c-130"])
def test_interrupted_deploy_exits_with_a_true_summary_and_resume_finishes(
        tmp_path: Path, sig: int, status: int, until: Callable[[Records], bool], what: str) -> None:
    mission, d = write_resume_mission(tmp_path)
    run_dir = tmp_path / "run"
    with sim_process(mission, tmp_path / "sim.log") as sim:
        with controller(["deploy", "--mission", str(mission), "--run-dir", str(run_dir), "--headless",
                         "--yes"], tmp_path / "fly.log") as fly:
            wait_journal(fly, run_dir, until, what)
            rc = fly.signal(sig)
            out = fly.output()
        seen = observe_fleet(mission)
        assert rc == status, f"{signal.Signals(sig).name}: exit {rc} (want {status}):\n{out[-3000:]}"
        killed_lines = journal_lines(run_dir)
        p = Problems()
        p.prefix = f"{signal.Signals(sig).name}: "
        context = check_interrupted(p, out, parse_journal_strict(run_dir), read_summary(run_dir), seen,
                                    run_dir)

        # the interrupted run can be finished
        rc, out = run_ctl(["resume", "--run", str(run_dir), "--headless", "--yes"], tmp_path / "resume.log")
        seen = observe_fleet(mission)
        assert sim.proc.poll() is None, sim.output()
    p.prefix = "resume: "
    context += check_resumed(p, rc, out, run_dir, killed_lines, seen, d, run=False)
    p.assert_none(*context)


# ---------------------------------------------------------------------------------------------------
# what resume refuses
# ---------------------------------------------------------------------------------------------------


def _error_line(out: str) -> str:
    return next((ln for ln in out.splitlines() if ln.startswith("fleetctl: error:")), "")


def test_resume_refuses_another_mission_file_then_takes_the_same_one(tmp_path: Path) -> None:
    mission, d = write_resume_mission(tmp_path)
    other_d = yaml.safe_load(mission.read_text())
    other_d["tasks"][1]["position"] = [82, -16, 4]  # same name, same fleet, one task moved
    other = write_mission(other_d, tmp_path / "other.yaml")
    run_dir = tmp_path / "run"
    with sim_process(mission, tmp_path / "sim.log") as sim:
        with controller(["deploy", "--mission", str(mission), "--run-dir", str(run_dir), "--headless",
                         "--yes"], tmp_path / "fly.log") as fly:
            wait_journal(fly, run_dir, lambda rs: bool(of_kind(rs, "rover_launched")),
                         "a rover_launched record")
            fly.kill9()
        killed_lines = journal_lines(run_dir)

        rc, out = run_ctl(["resume", "--run", str(run_dir), "--headless", "--yes", "--mission", str(other)],
                          tmp_path / "other.log", timeout=30)
        assert rc == 2, f"exit {rc}:\n{out[-3000:]}"
        assert "Traceback" not in out, out[-3000:]
        err = _error_line(out)
        assert "other.yaml" in err and any(w in err for w in ("differ", "mismatch", "not the mission",
                                                               "does not match")), out[-2000:]
        assert journal_lines(run_dir) == killed_lines, "a refused resume wrote to the journal"

        # the saved copy's own file is accepted, and the run is finished
        rc, out = run_ctl(["resume", "--run", str(run_dir), "--headless", "--yes", "--mission", str(mission)],
                          tmp_path / "resume.log")
        seen = observe_fleet(mission)
        assert sim.proc.poll() is None, sim.output()
    p = Problems()
    p.assert_none(*check_resumed(p, rc, out, run_dir, killed_lines, seen, d, run=False))


def test_resume_refuses_a_folder_without_journal(tmp_path: Path) -> None:
    mission, _d = write_resume_mission(tmp_path)
    empty = tmp_path / "norun"
    empty.mkdir()
    (empty / "mission.yaml").write_text(mission.read_text())  # a mission copy alone is not a run
    for folder in (empty, tmp_path / "does-not-exist"):
        rc, out = run_ctl(["resume", "--run", str(folder), "--headless", "--yes"], tmp_path / "resume.log",
                          timeout=30)
        assert rc == 2, f"{folder}: exit {rc}:\n{out[-2000:]}"
        assert "Traceback" not in out, out[-2000:]
        err = _error_line(out)
        assert "journal" in err and str(folder.name) in err, out[-2000:]
    assert not (empty / "journal.jsonl").exists() and not (empty / "summary.json").exists()


def test_resume_refuses_a_run_on_the_embedded_sim(tmp_path: Path) -> None:
    path = write_mission(mission_dict(rovers=2, speedup=20.0), tmp_path / "sim.yaml")  # connection: sim
    run_dir = tmp_path / "simrun"
    with controller(["deploy", "--mission", str(path), "--run-dir", str(run_dir), "--headless"],
                    tmp_path / "fly.log") as fly:
        wait_journal(fly, run_dir, lambda rs: bool(of_kind(rs, "plan")), "a plan record")
        rc = fly.signal(signal.SIGTERM)
        fly_out = fly.output()
    assert rc == 143, f"SIGTERM: exit {rc}:\n{fly_out[-2000:]}"
    before = journal_lines(run_dir)
    rc, out = run_ctl(["resume", "--run", str(run_dir), "--headless"], tmp_path / "resume.log",
                      timeout=30)
    assert rc == 2, f"exit {rc}:\n{out[-3000:]}"
    assert "Traceback" not in out, out[-3000:]
    err = _error_line(out)
    assert "embedded" in err and "died" in err, out[-2000:]
    assert journal_lines(run_dir) == before, "a refused resume wrote to the journal"
