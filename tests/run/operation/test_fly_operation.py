"""`fleetctl run` flies a long operation on the embedded simulated fleet: sorties launched,
tasks worked for their durations (timed by the firmware), rovers picked up, batteries swapped,
every rover back on the deck."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Any

from fleetctl.mission import Mission
from fleetctl.run.flight import execute
from fleetctl.run.lifecycle import RunOutcome
from sitl import SimFleet
from sitl.world import Phase as BodyPhase
from tests.run.ctl_helpers import mission_from, write_mission
from tests.run.operation.ops_helpers import drop_battery, journal, small_operation


async def test_a_small_operation_flies_to_complete(tmp_path: Path) -> None:
    mission = mission_from(small_operation(), tmp_path)
    out = await asyncio.wait_for(execute(mission, "run", run_dir=tmp_path / "run", force=True), 120)
    s = out.summary
    assert out.exit_code == 0, s
    assert s["result"] == "complete"
    tasks = {t.id: mission.task_work(t.id).duration for t in mission.tasks}
    assert sorted(s["tasks_done"]) == sorted(tasks) == sorted(s["tasks_reached"])
    assert sorted(s["rovers_loaded"]) == ["r1", "r2"] and not s["rovers_lost"]
    records = journal(tmp_path / "run")
    done = [r for r in records if r["kind"] == "task_done"]
    assert sorted(r["task"] for r in done) == sorted(tasks)  # each task worked once
    for r in done:  # for its duration: the firmware timed it (a landed task counts its touch-down too)
        # seen on the controller's clock as the messages came in: 1 s of mission time is 50 ms of wall time
        assert r["worked"] >= tasks[r["task"]] - 1.0, r
    launched = [r for r in records if r["kind"] == "sortie_launched"]
    back = [r for r in records if r["kind"] == "sortie_back"]
    assert len(launched) == len(back) > 2  # rovers fly again: more sorties than rovers
    plan = json.loads((tmp_path / "run" / "plan.json").read_text())
    swaps = [r for r in records if r["kind"] == "battery_swapped"]
    planned = [e for rows in plan["rovers"].values() for e in rows if e["kind"] == "swap"]
    assert len(swaps) == len(planned) >= 1  # every planned swap flown and journalled
    assert s["makespan_flown"] is not None and s["makespan_planned"] is not None


async def test_a_rover_lost_mid_operation_is_replanned_around(tmp_path: Path) -> None:
    d = small_operation()
    d["links"] = {"heartbeat_timeout": 1.0}
    mission = mission_from(d, tmp_path)
    watchers: list[asyncio.Task[None]] = []

    async def kill_r1_on_its_first_task(sim: SimFleet) -> None:
        r1 = sim.rover("r1")
        await sim.wait_for(lambda: r1.phase is BodyPhase.AIR, 60)
        t = sim.sim_time
        await sim.wait_sim_time(t + 20.0, 60)  # working its first task
        sim.dropout("r1")  # never back

    def on_sim(sim: SimFleet) -> None:
        watchers.append(asyncio.ensure_future(kill_r1_on_its_first_task(sim)))

    out = await asyncio.wait_for(execute(mission, "run", run_dir=tmp_path / "run", force=True, on_sim=on_sim),
                                 150)
    for w in watchers:
        w.cancel()
    s = out.summary
    records = journal(tmp_path / "run")
    lost = [r for r in records if r["kind"] == "sortie_lost"]
    assert [r["vehicle"] for r in lost] == ["r1"] and lost[0]["tasks_left"], lost
    replans = [r for r in records if r["kind"] == "replan" and "error" not in r]
    assert any("rover r1 lost" in r["cause"] for r in replans)
    assert s["rovers_lost"] == ["r1"] and s["rovers_loaded"] == ["r2"]
    tasks = sorted(t.id for t in mission.tasks)
    assert sorted(s["tasks_done"]) == tasks  # the lost rover's work was done by the other
    done_by = {r["task"]: r["vehicle"] for r in records if r["kind"] == "task_done"}
    assert all(done_by[t] == "r2" for t in lost[0]["tasks_left"])
    assert (tmp_path / "run" / "plan-replan-1.json").exists()


async def test_a_battery_too_low_for_the_next_sortie_is_replanned_from(tmp_path: Path) -> None:
    d = small_operation()
    d["sim"]["faults"] = [{"vehicle": "r1", "kind": "battery_drain", "factor": 1.3}]
    mission = mission_from(d, tmp_path)
    out = await asyncio.wait_for(execute(mission, "run", run_dir=tmp_path / "run", force=True), 150)
    records = journal(tmp_path / "run")
    replans = [r for r in records if r["kind"] == "replan" and "error" not in r]
    assert any("rover r1 back with" in r["cause"] for r in replans), [r.get("text") for r in records
                                                                      if r["kind"] == "replan"]
    assert out.exit_code == 0, out.summary
    assert sorted(out.summary["tasks_done"]) == sorted(t.id for t in mission.tasks)


async def test_a_battery_reading_low_in_the_air_asks_for_a_replan(tmp_path: Path) -> None:
    """r2's battery drops to 55 % just after its launch on a sortie (t2, t1) planned for a full one:
    the replan at the next stop (r1's pick-up) is asked for by r2's reading in the air, before r2
    is back (on the deck only, its reading would not be seen before it lands)."""
    mission = mission_from(small_operation(), tmp_path)
    watchers: list[asyncio.Task[None]] = []

    def on_sim(sim: SimFleet) -> None:
        watchers.append(asyncio.ensure_future(drop_battery(sim, "r2", 0.55, tmp_path / "run")))

    await asyncio.wait_for(execute(mission, "run", run_dir=tmp_path / "run", force=True, on_sim=on_sim), 150)
    for w in watchers:
        w.cancel()
    records = journal(tmp_path / "run")
    asked = [i for i, r in enumerate(records) if r["kind"] == "replan"
             and "rover r2 at" in r["cause"] and "in the air" in r["cause"]]
    back = [i for i, r in enumerate(records) if r["kind"] in ("sortie_back", "sortie_lost")
            and r.get("vehicle") == "r2"]
    assert asked and back and asked[0] < back[0], [r.get("text") for r in records if r["kind"] == "replan"]


async def run_editing_after_the_first_launch(mission: Mission, edited: dict[str, Any],
                                             tmp_path: Path) -> RunOutcome:
    """Fly ``run`` of ``mission`` (its file in ``tmp_path``), writing ``edited`` over the mission file
    once r1 is first in the air."""
    watchers: list[asyncio.Task[None]] = []

    async def edit_after_the_first_launch(sim: SimFleet) -> None:
        r1 = sim.rover("r1")
        await sim.wait_for(lambda: r1.phase is BodyPhase.AIR, 60)
        write_mission(edited, tmp_path / "mission.yaml")

    def on_sim(sim: SimFleet) -> None:
        watchers.append(asyncio.ensure_future(edit_after_the_first_launch(sim)))

    try:
        return await asyncio.wait_for(execute(mission, "run", run_dir=tmp_path / "run", force=True,
                                              on_sim=on_sim), 150)
    finally:
        for w in watchers:
            w.cancel()


async def test_tasks_added_and_removed_in_the_mission_file_are_flown(tmp_path: Path) -> None:
    d = small_operation()
    mission = mission_from(d, tmp_path)
    edited = small_operation()
    edited["tasks"] = [t for t in edited["tasks"] if t["id"] != "t6"]
    edited["tasks"].append({"id": "t7", "position": [30, -10, 4], "duration": 45})  # dwell: 20
    out = await run_editing_after_the_first_launch(mission, edited, tmp_path)
    s = out.summary
    assert out.exit_code == 0, s
    assert s["tasks_added"] == ["t7"] and s["tasks_removed"] == ["t6"]
    assert sorted(s["tasks_done"]) == ["t1", "t2", "t3", "t4", "t5", "t7"]
    records = journal(tmp_path / "run")
    assert any(r["kind"] == "replan" and "tasks changed" in r.get("cause", "") for r in records)
    done = {r["task"]: r["worked"] for r in records if r["kind"] == "task_done"}
    # an added task's work: the duration the edit gives it (45 s), not the dwell (20 s); as the
    # controller saw it: the MISSION_ITEM_REACHED at its start and end each come up to a few tens of
    # wall ms late on a busy machine, seconds of mission time at speed-up 20
    assert done["t7"] >= 45 - 5.0


async def test_a_rover_short_of_battery_in_the_air_is_called_back_early(tmp_path: Path) -> None:
    """r2's battery drops to 50 % just after its launch on a sortie (t2, t1) that needs about two
    thirds of a battery: the carrier, waiting at its stop for r1, stops waiting and replans at once;
    the replan calls r2 back early (its tasks dropped from its sortie), r2 lands before r1's pick-up,
    and the tasks it dropped are worked in full by later sorties, once each."""
    mission = mission_from(small_operation(), tmp_path)
    watchers: list[asyncio.Task[None]] = []

    def on_sim(sim: SimFleet) -> None:
        watchers.append(asyncio.ensure_future(drop_battery(sim, "r2", 0.5, tmp_path / "run")))

    out = await asyncio.wait_for(execute(mission, "run", run_dir=tmp_path / "run", force=True, on_sim=on_sim),
                                 150)
    for w in watchers:
        w.cancel()
    records = journal(tmp_path / "run")
    called = [r for r in records if r["kind"] == "sortie_called_back"]
    assert [r["vehicle"] for r in called] == ["r2"] and called[0]["tasks"], [r.get("text") for r in records
                                                                              if r["kind"] == "replan"]
    plan = json.loads((tmp_path / "run" / "plan-replan-1.json").read_text())
    assert plan["called_back"] == {"r2": called[0]["tasks"]}
    back = [r["vehicle"] for r in records if r["kind"] == "sortie_back"]
    assert back[0] == "r2"  # called back: on the deck before r1 ends its first sortie
    assert out.exit_code == 0, out.summary
    durations = {t.id: mission.task_work(t.id).duration for t in mission.tasks}
    done = [r for r in records if r["kind"] == "task_done"]
    assert sorted(r["task"] for r in done) == sorted(durations)  # each task's work done once
    for r in done:
        if r["task"] in called[0]["tasks"]:  # dropped by r2: worked in full by another sortie
            assert r["sortie"] != called[0]["sortie"] and r["worked"] >= durations[r["task"]] - 1.0, r


async def test_a_rover_into_its_reserve_is_brought_back_by_a_recovery_plan(tmp_path: Path) -> None:
    """r2's battery reads 8 % just after its launch, below the 10 % reserve: no schedule keeps every
    reserve, so the replan is a recovery (nothing launched, r2 called back at once, the reserve
    given up); once the rovers it brings back are aboard, the tasks left are planned and flown.
    (Acted on late, at 4 % and further out, r2 could not come back: no recovery plan exists then;
    :func:`drop_battery` holds the reading and flies the fleet in real time until the replan.)"""
    mission = mission_from(small_operation(), tmp_path)
    watchers: list[asyncio.Task[None]] = []

    def on_sim(sim: SimFleet) -> None:  # just after the launch
        watchers.append(asyncio.ensure_future(drop_battery(sim, "r2", 0.08, tmp_path / "run")))

    out = await asyncio.wait_for(execute(mission, "run", run_dir=tmp_path / "run", force=True, on_sim=on_sim),
                                 150)
    for w in watchers:
        w.cancel()
    records = journal(tmp_path / "run")
    replans = [r for r in records if r["kind"] == "replan"]
    assert replans and replans[0].get("recovery") is True, [r.get("text") for r in replans]
    plan = json.loads((tmp_path / "run" / "plan-replan-1.json").read_text())
    assert plan["recovery"] is True and plan["time_model"]["reserve"] == 0.0
    assert all(s["launch_stop"] == -1 for s in plan["sorties"]) and plan["called_back"]["r2"]
    # the tasks left are planned once the sortie it called back is over: at the end of its route
    # ("the rovers called back by a recovery plan are aboard") or, when a battery read at their
    # pick-up asks for a replan there, at that stop; on a starved machine r2 (5 %) may not make it
    # back in time and is given up (sortie_lost, "rover r2 lost")
    assert len(replans) >= 2 and replans[1].get("recovery") is False, [r.get("text") for r in replans]
    over = next(i for i, r in enumerate(records)
                if r["kind"] in ("sortie_back", "sortie_lost") and r["vehicle"] == "r2")
    assert records.index(replans[1]) > over
    assert out.exit_code == 0, out.summary
    assert sorted(out.summary["tasks_done"]) == sorted(t.id for t in mission.tasks)  # the rest flown after


async def test_a_task_s_duration_alone_edited_in_the_mission_file_is_replanned(tmp_path: Path) -> None:
    """t4's duration goes from 15 s to 40 s in the mission file after the first launch (t4 is not in
    a sortie yet): the edit is a task change, the rest is replanned, t4 is worked for 40 s."""
    mission = mission_from(small_operation(), tmp_path)
    edited = small_operation()
    next(t for t in edited["tasks"] if t["id"] == "t4")["duration"] = 40
    out = await run_editing_after_the_first_launch(mission, edited, tmp_path)
    s = out.summary
    assert out.exit_code == 0, s
    assert not s["tasks_added"] and not s["tasks_removed"]
    records = journal(tmp_path / "run")
    changed = [r for r in records if r["kind"] == "tasks_changed"]
    assert [[t["id"], t["duration"]] for r in changed for t in r["retimed"]] == [["t4", 40.0]]
    assert any(r["kind"] == "replan" and "tasks changed" in r.get("cause", "") for r in records)
    done = {r["task"]: r for r in records if r["kind"] == "task_done"}
    assert sorted(done) == sorted(t.id for t in mission.tasks)
    assert done["t4"]["duration"] == 40.0 and done["t4"]["worked"] >= 40 - 1.0  # the new duration, not 15 s


async def test_a_battery_dropping_while_a_rover_works_is_seen_before_the_work_ends(tmp_path: Path) -> None:
    """r2's battery drops to 35 % early in its first task (t2, 30 s of hovering, then t1): the reading
    is looked at while it works, so the replan is asked for (and r2 called back) before r2 reports any
    task done (:func:`drop_battery` flies the fleet in real time until the replan: at 20x the rest of
    t2 is 1.3 wall s, which a loaded machine's event loop may spend elsewhere)."""
    mission = mission_from(small_operation(), tmp_path)
    watchers: list[asyncio.Task[None]] = []

    def on_sim(sim: SimFleet) -> None:  # at t2 (arrives ~4 s after take-off), working
        watchers.append(asyncio.ensure_future(drop_battery(sim, "r2", 0.35, tmp_path / "run", after=8.0)))

    out = await asyncio.wait_for(execute(mission, "run", run_dir=tmp_path / "run", force=True, on_sim=on_sim),
                                 150)
    for w in watchers:
        w.cancel()
    records = journal(tmp_path / "run")
    started = [i for i, r in enumerate(records) if r["kind"] == "task_started" and r["vehicle"] == "r2"]
    asked = [i for i, r in enumerate(records)
             if r["kind"] == "replan" and "rover r2 at" in r.get("cause", "")]
    done = [i for i, r in enumerate(records) if r["kind"] == "task_done" and r["vehicle"] == "r2"]
    assert started and asked and started[0] < asked[0] < done[0], [r.get("text") for r in records]
    assert any(r["kind"] == "sortie_called_back" and r["vehicle"] == "r2" for r in records)
    assert out.exit_code == 0, out.summary
    assert sorted(out.summary["tasks_done"]) == sorted(t.id for t in mission.tasks)


async def test_ground_work_on_ardupilot_is_timed_by_the_controller(tmp_path: Path) -> None:
    """ArduCopter ends a mission at its NAV_LAND (it disarms on the ground and restarts the mission;
    the simulated fleet's ArduPilot flavour does the same): a sortie ends at a task worked on the
    ground, the controller times the work from the touch-down, then uploads, arms and starts the
    rest (``sortie_continued``). Every task is worked for its duration and every rover comes back."""
    from fleetctl.run.sim import sim_mission_dict
    from sitl import FleetConfig

    mission = mission_from(small_operation(), tmp_path)
    cfg = FleetConfig.from_mission_dict(sim_mission_dict(mission), autopilot="ardupilot")
    async with SimFleet(cfg) as sim:
        out = await asyncio.wait_for(execute(mission, "run", sim=sim, run_dir=tmp_path / "run", force=True),
                                     180)
        assert sim.errors == 0, sim.last_error
    s = out.summary
    assert out.exit_code == 0 and s["result"] == "complete", s
    tasks = {t.id: mission.task_work(t.id) for t in mission.tasks}
    assert sorted(s["tasks_done"]) == sorted(tasks)
    records = journal(tmp_path / "run")
    done = {r["task"]: r for r in records if r["kind"] == "task_done"}
    ground = [t for t, w in tasks.items() if w.ground]
    assert ground and all(done[t]["worked"] >= tasks[t].duration for t in ground), done
    launched = [r for r in records if r["kind"] == "sortie_launched"]
    for r in launched:  # each launched mission ends at its first task worked on the ground
        firsts = [t for t in r["tasks"] if tasks[t].ground][:1]
        assert [w[0] for w in r["work"] if w[2] < 0] == firsts, r
    continued = [r for r in records if r["kind"] == "sortie_continued"]
    # a sortie with work on the ground before its last task flies on after it
    if any(tasks[t].ground for r in launched for t in r["tasks"][:-1]):
        assert continued and all(r["work"] for r in continued), continued
    assert sorted(s["rovers_loaded"]) == ["r1", "r2"] and not s["rovers_lost"]


async def test_a_task_added_while_the_carrier_drives_is_replanned_on_the_way(tmp_path: Path) -> None:
    # a first drive of ~13 mission s at speed-up 4: the file watch (0.5 wall s) sees the edit on the way
    changes = {"sim": {"speedup": 4.0, "faults": []}}
    d = small_operation(**changes)
    d["carrier"]["position"] = [-40, 0]
    mission = mission_from(d, tmp_path)
    edited = small_operation(**changes)
    edited["carrier"]["position"] = [-40, 0]
    edited["tasks"].append({"id": "t7", "position": [-30, 10, 4], "duration": 15})  # behind the carrier
    watchers: list[asyncio.Task[None]] = []

    async def edit_while_driving(sim: SimFleet) -> None:
        carrier = sim.body("carrier")
        await sim.wait_for(lambda: abs(carrier.vel[0]) + abs(carrier.vel[1]) > 1.0, 60)
        write_mission(edited, tmp_path / "mission.yaml")

    def on_sim(sim: SimFleet) -> None:
        watchers.append(asyncio.ensure_future(edit_while_driving(sim)))

    try:
        out = await asyncio.wait_for(execute(mission, "run", run_dir=tmp_path / "run", force=True,
                                             on_sim=on_sim), 150)
    finally:
        for w in watchers:
            w.cancel()
    s = out.summary
    assert out.exit_code == 0, s
    assert "t7" in s["tasks_done"]
    records = journal(tmp_path / "run")
    first_stop = next(r["elapsed"] for r in records if r["kind"] == "stop_reached")
    replan = next(r for r in records if r["kind"] == "replan" and "tasks changed" in r.get("cause", ""))
    assert replan["elapsed"] < first_stop, (replan, first_stop)  # made on the way, not at the stop
    paused = [r for r in records if r["kind"] == "hold" and r.get("vehicle") == "carrier"]
    assert paused and paused[0]["elapsed"] < replan["elapsed"]
    starts = [r["elapsed"] for r in records if r["kind"] == "carrier_started"]
    assert len(starts) >= 2 and starts[1] < first_stop  # the new route from where it was paused


def test_the_docs_state_the_terms_of_a_replan_on_the_way() -> None:
    from fleetctl.run.operation.phase import DRIVE_REPLAN_MIN, PAUSE_WAIT
    text = (Path(__file__).resolve().parents[3] / "docs" / "operations.md").read_text(encoding="utf-8")
    part = text[text.index("#### Replanning on the way"):text.index("#### Early call-back")]
    section = " ".join(part.split())
    for phrase in (f"{DRIVE_REPLAN_MIN:g} mission seconds (`DRIVE_REPLAN_MIN`)",
                   f"at most {PAUSE_WAIT:g} mission s: `PAUSE_WAIT`", "`DO_PAUSE_CONTINUE`",
                   "a `hold` record"):
        assert phrase in section, phrase
