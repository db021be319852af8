"""``fleetctl resume`` finishes a long operation whose controller was killed (``kill -9``) while a
rover worked a task, or while one flew back to its pick-up: the simulated fleet is served by
``fleetctl sim`` in its own process (it outlives the controller, as a real fleet does) and the
controller runs as a subprocess against it, as in tests/run/test_resume.py. After the resume, the
journal must show every task's work done exactly once in total (never a task done twice), each for
its full duration (measured by the controller, or timed by the firmware while the controller was
down), every sortie launched back on the deck, a complete summary, and the simulated world every
rover on the deck."""

from __future__ import annotations

import signal
from collections import Counter
from pathlib import Path
from typing import Any

import pytest

from tests.run.ctl_helpers import free_udp_port, write_mission
from tests.run.operation.ops_helpers import small_operation
from tests.run.resume_helpers import (
    Problems,
    Records,
    controller,
    describe,
    journal_lines,
    kinds_summary,
    observe_fleet,
    of_kind,
    on_deck,
    parse_journal_strict,
    read_summary,
    run_ctl,
    sim_process,
    wait_journal,
)

pytestmark = pytest.mark.slow

# the sim's and the controller's (--speedup on a real URL: the controller's clock follows). Rovers
# in the air burn their battery while the controller is down and while the resume connects: on a
# loaded 2-core machine 3 - 4 wall s, 30 - 40 mission s at speed-up 10, more than a plan that flies
# its sorties down to the reserve leaves (the resume then finds no plan); 15 - 20 s at 5
SPEEDUP = 5.0
CTL_TIMEOUT = 120.0  # wall s for a run or a resume of the small operation


def _operation(tmp_path: Path) -> tuple[Path, dict[str, Any]]:
    d = small_operation()
    d["carrier"]["connection"] = f"udp://127.0.0.1:{free_udp_port()}"
    d["sim"] = {"speedup": SPEEDUP, "faults": []}
    return write_mission(d, tmp_path / "mission.yaml"), d


def _working_after_a_task_done(recs: Records) -> bool:
    """A task's work done, and another being worked (started, not done)."""
    done = {r["task"] for r in of_kind(recs, "task_done")}
    started = {r["task"] for r in of_kind(recs, "task_started")}
    return bool(done) and bool(started - done)


def _returning(recs: Records) -> bool:
    """A rover on its way back to its pick-up stop (not loaded yet)."""
    back = {r["sortie"] for r in of_kind(recs, "sortie_back")}
    return any(r["sortie"] not in back for r in of_kind(recs, "sortie_returning"))


KILL_AT = {"working": (_working_after_a_task_done, "a task being worked after a task_done"),
           "returning": (_returning, "a sortie_returning record of a sortie not back")}


def _check_resumed_operation(p: Problems, recs: Records, killed: Records, d: dict[str, Any],
                             summary: dict[str, Any]) -> None:
    durations = {t["id"]: float(t.get("duration", d["dwell"])) for t in d["tasks"]}
    done = of_kind(recs, "task_done")
    count = Counter(r["task"] for r in done)
    p.check(set(count) == set(durations), f"tasks with a task_done record {sorted(count)} (want all)")
    p.check(all(n == 1 for n in count.values()), f"a task done twice: {dict(count)}")
    found = of_kind(recs, "resumed")[0].get("found", {}) if of_kind(recs, "resumed") else {}
    started_unseen = {r["task"] for r in of_kind(recs, "task_started") if r.get("found") == "on resume"}
    for r in done:
        if r.get("worked") is None:  # done, or started, while the controller was down: the firmware timed it
            p.check((r.get("found") == "on resume" and r["task"] in found.get("done_while_down", []))
                    or r["task"] in started_unseen, f"task_done without 'worked' not found on resume: {r}")
        else:  # measured as the messages came in: 1 mission s is 100 ms of wall time at 10x
            p.check(r["worked"] >= durations[r["task"]] - 1.0, f"task worked less than its duration: {r}")
    launched = [r["sortie"] for r in of_kind(recs, "sortie_launched")]
    back = [r["sortie"] for r in of_kind(recs, "sortie_back")]
    p.check(sorted(launched) == sorted(back) and len(set(launched)) == len(launched),
            f"sorties launched {launched}, back {back} (want each launched once and back)")
    p.check(not of_kind(recs, "sortie_lost"), "a sortie lost")
    p.check(summary.get("result") == "complete", f"summary result {summary.get('result')!r}")
    p.check(sorted(summary.get("tasks_done", [])) == sorted(durations), f"summary tasks_done "
            f"{summary.get('tasks_done')}")
    p.check(sorted(summary.get("rovers_loaded", [])) == ["r1", "r2"], f"summary rovers_loaded "
            f"{summary.get('rovers_loaded')}")
    killed_done = {r["task"] for r in of_kind(killed, "task_done")}
    p.check(not killed_done & {r["task"] for r in done[len(of_kind(killed, "task_done")):]},
            "a task done before the kill was done again after it")


@pytest.mark.parametrize("moment", list(KILL_AT))
def test_kill_9_mid_operation_then_resume_finishes_it(tmp_path: Path, moment: str) -> None:
    until, what = KILL_AT[moment]
    mission, d = _operation(tmp_path)
    run_dir = tmp_path / "run"
    with sim_process(mission, tmp_path / "sim.log", speedup=SPEEDUP, vehicles=3) as sim:
        with controller(["run", "--mission", str(mission), "--run-dir", str(run_dir), "--headless", "--yes",
                         "--speedup", str(SPEEDUP)], tmp_path / "fly.log") as fly:
            wait_journal(fly, run_dir, until, what, timeout=CTL_TIMEOUT)
            rc = fly.kill9()
        assert rc == -signal.SIGKILL
        killed_lines = journal_lines(run_dir)
        killed = parse_journal_strict(run_dir)
        assert not of_kind(killed, "operation_done"), "the operation ended before the kill (test timing)"
        rc, out = run_ctl(["resume", "--run", str(run_dir), "--headless", "--yes", "--speedup", str(SPEEDUP)],
                          tmp_path / "resume.log", timeout=CTL_TIMEOUT)
        seen = observe_fleet(mission)
        assert sim.proc.poll() is None, sim.output()
    recs = parse_journal_strict(run_dir)
    p = Problems()
    p.check(rc == 0, f"resume exited {rc} (want 0)")
    p.check("Traceback" not in out, "a traceback in the output of resume")
    p.check(journal_lines(run_dir)[:len(killed_lines)] == killed_lines, "resume rewrote the journal")
    p.check(len(of_kind(recs[len(killed):], "resumed")) == 1, "not one 'resumed' record appended")
    p.check(any(r.get("cause", "").startswith("resumed") for r in of_kind(recs, "replan")),
            "no replan from the live state on resume")
    _check_resumed_operation(p, recs, killed, d, read_summary(run_dir))
    p.check(on_deck(seen) == {"r1", "r2"}, "the world: not every rover is back on the deck")
    p.assert_none(f"journal:\n{kinds_summary(recs)}", f"the world:\n{describe(seen)}",
                  f"resume output:\n{out[-2500:]}")
