"""fleetctl replay: a run folder's journal and MAVLink log played back in mission time."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from views_helpers import write_run

from fleetctl.cli import main
from fleetctl.mission import Mission
from fleetctl.views.replay import CHUNK, Player, ReplayError, ReplayState, load_run, replay, timeline

SPEEDUP = 2.0  # the recorded run's mission seconds per wall second


class Sleeps:
    """A fake wall-clock wait: records what it was asked to wait and returns at once."""

    def __init__(self) -> None:
        self.waits: list[float] = []

    async def __call__(self, seconds: float) -> None:
        self.waits.append(seconds)


def _history(state: ReplayState, steps: list, vid: str) -> list[tuple[float, str]]:
    out: list[tuple[float, str]] = []
    for step in steps:
        state.apply(step)
        s = state.vehicles[vid].state
        if not out or out[-1][1] != s:
            out.append((state.now, s))
    return out


def test_journal_and_tlog_become_states_in_mission_order(tmp_path: Path) -> None:
    run = load_run(write_run(tmp_path / "run", speedup=SPEEDUP))
    steps = timeline(run)
    assert [s.T for s in steps] == sorted(s.T for s in steps)
    state = ReplayState(run.mission)
    rover = _history(state, steps, "r1")
    assert [s for _, s in rover] == ["unknown", "on_deck", "climbing", "en_route", "on_task"]
    # mission time = wall time since the run record x the run's speedup: launched 2.5 s wall in
    assert rover[2][0] == pytest.approx(2.5 * SPEEDUP)
    assert rover[-1][0] == pytest.approx(7.5 * SPEEDUP)
    e, n, _ = state.vehicles["r1"].enu or (0, 0, 0)
    assert math.hypot(e - 20, n - 10) < 0.5  # the last telemetry: at the task
    assert state.phase == "done" and state.stop_index == 1 and state.plan is not None


def test_carrier_stops_and_plan_start_follow_the_records(tmp_path: Path) -> None:
    run = load_run(write_run(tmp_path / "run", speedup=SPEEDUP))
    state = ReplayState(run.mission)
    carrier = _history(state, timeline(run), "carrier")
    assert [s for _, s in carrier] == ["idle", "driving", "holding"]  # idle from the run record on
    assert state.plan_started == pytest.approx(1.0 * SPEEDUP)  # carrier_started


@pytest.mark.parametrize("sim", [True, False])
def test_events_carry_the_one_time_base(tmp_path: Path, sim: bool) -> None:
    d = write_run(tmp_path / "run", speedup=SPEEDUP, sim=sim)
    lines = (d / "journal.jsonl").read_text().splitlines()
    recs = [json.loads(x) for x in lines]
    recs[3]["T"] = 1.25  # carrier_started, 1.0 s wall into the run, knows its mission time
    recs[6]["T"] = 20.0  # task_reached, 7.5 s wall in: the simulator ran faster than 2x meanwhile
    (d / "journal.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs))
    state = ReplayState(load_run(d).mission)
    for step in timeline(load_run(d)):
        state.apply(step)
    times = {ev.kind: ev.mission_time for ev in state.events}
    # the simulator's T is kept; real vehicles' records go by the wall clock (T restarts on resume)
    assert times["carrier_started"] == pytest.approx(1.25 if sim else 1.0 * SPEEDUP)
    assert times["task_reached"] == pytest.approx(20.0 if sim else 7.5 * SPEEDUP)
    # telemetry between them on the simulator's clock too: r1's sample 4.0 s wall in (f = 3/6.5)
    sample_t = [s.T for s in timeline(load_run(d)) if s.sample is not None and s.sample.vehicle == "r1"]
    expected = 1.25 + (4.0 - 1.0) / 6.5 * (20.0 - 1.25) if sim else 4.0 * SPEEDUP
    assert sample_t[4] == pytest.approx(expected)


@pytest.mark.parametrize("speed", [1.0, 4.0])
async def test_speed_scales_the_waits(tmp_path: Path, speed: float) -> None:
    run = load_run(write_run(tmp_path / "run", speedup=SPEEDUP))
    last = timeline(run)[-1].T
    sleeps = Sleeps()
    state = await replay(run, None, speed=speed, sleep=sleeps)
    assert sum(sleeps.waits) == pytest.approx(last / speed)
    assert max(sleeps.waits) <= CHUNK + 1e-9  # in short waits, so the views see the clock move
    assert state.now == pytest.approx(last)


async def test_speed_zero_never_waits(tmp_path: Path) -> None:
    run = load_run(write_run(tmp_path / "run"))
    sleeps = Sleeps()
    player = Player(timeline(run), ReplayState(run.mission), 0.0, sleeps)
    await player.play()
    assert sleeps.waits == [] and player.state.vehicles["r1"].state == "on_task"


async def test_views_are_started_and_stopped(tmp_path: Path) -> None:
    run = load_run(write_run(tmp_path / "run"))
    seen: list[str] = []

    class Spy:
        def start(self, state: object, fleet: object) -> None:
            seen.append("start")

        async def stop(self) -> None:
            seen.append("stop")

    await replay(run, Spy(), speed=0.0)  # type: ignore[arg-type]
    assert seen == ["start", "stop"]


def _break(d: Path, how: str) -> None:
    j = d / "journal.jsonl"
    if how == "no journal":
        j.unlink()
    elif how == "corrupt":
        lines = j.read_text().splitlines()
        lines[2] = "{not json"
        j.write_text("\n".join(lines) + "\n")
    elif how == "not a run":
        j.write_text(json.dumps({"t": 1.0, "kind": "plan"}) + "\n")
    elif how == "no mission":
        (d / "mission.yaml").unlink()


@pytest.mark.parametrize(("how", "says"), [
    ("missing", "no such run folder"), ("no journal", "not a run folder"), ("corrupt", "corrupt journal"),
    ("not a run", "does not start with a 'run' record"), ("no mission", "no mission.yaml")])
def test_bad_run_folders_are_refused_clearly(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                             how: str, says: str) -> None:
    d = tmp_path / "run"
    if how != "missing":
        write_run(d)
        _break(d, how)
    with pytest.raises(ReplayError, match=says):
        load_run(d)
    assert main(["replay", str(d), "--headless"]) == 2
    err = capsys.readouterr().err
    assert says in err and "Traceback" not in err


def test_cli_replays_instantly_and_prints_the_final_table(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    d = write_run(tmp_path / "run")
    assert main(["replay", str(d), "--instant", "--headless"]) == 0
    out = capsys.readouterr().out
    assert "r1: reached t1" in out and f"T+{7.5 * SPEEDUP:.1f}s" in out
    assert "on_task" in out  # the fleet table at the end


def test_a_runs_dwell_is_its_planned_time(tmp_path: Path) -> None:
    d = write_run(tmp_path / "run", speedup=SPEEDUP)
    recs = [json.loads(x) for x in (d / "journal.jsonl").read_text().splitlines()]
    recs[0]["command"], recs[0]["dwell"] = "run", 30.0
    recs.insert(-1, {"t": recs[-1]["t"] - 0.1, "elapsed": 7.9, "kind": "phase", "phase": "dwell"})
    (d / "journal.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs))
    run = load_run(d)
    state = ReplayState(run.mission)
    for step in timeline(run):
        if step.record is not None and step.record["kind"] == "summary":
            break
        state.apply(step)
    assert state.phase == "dwell" and state.planned == 30.0  # the run's --dwell, not the mission's


def two_links_sharing_sysid_11(tmp_path: Path, c2_sysid: int) -> Mission:
    """Two carriers on simulated links of their own: r1 (c1's) and r3 (c2's) are both system id 11."""
    from views_helpers import ORIGIN

    from fleetctl.mission import load_mission

    team = {"connection": "sim", "max_speed": 10.0}
    mission = {"origin": ORIGIN, "rovers": {"max_speed": 5.0, "deploy_range": 40.0},
               "carriers": [{"id": "c1", "sysid": 1, "position": [0, 0], **team,
                             "units": [{"id": "r1", "sysid": 11}, {"id": "r2", "sysid": 12}]},
                            {"id": "c2", "sysid": c2_sysid, "position": [80, 0], **team,
                             "units": [{"id": "r3", "sysid": 11}, {"id": "r4", "sysid": 13}]}],
               "tasks": [{"id": "t1", "position": [5, 20, 3]}]}
    (tmp_path / "m.yaml").write_text(json.dumps(mission))
    return load_mission(tmp_path / "m.yaml")


def test_a_system_id_used_on_two_links_is_not_taken_from_the_log(tmp_path: Path) -> None:
    """The .tlog does not say which link a message came on: a system id two links use names no
    one vehicle, so its positions are left out; every other vehicle (every carrier too) is placed."""
    from views_helpers import position_msg

    from fleetctl.mavlink.tlog import tlog_record
    from fleetctl.views.replay import read_tlog

    m = two_links_sharing_sysid_11(tmp_path, c2_sysid=2)
    log = b"".join(tlog_record(1000.0 + k, position_msg(sysid, 10.0 * k, 0, 0))
                   for k, sysid in enumerate((1, 2, 11, 12, 13)))
    (tmp_path / "t.tlog").write_bytes(log)
    placed = [s.vehicle for s in read_tlog(tmp_path / "t.tlog", m)]
    assert placed == ["c1", "c2", "r2", "r4"]


def test_each_links_log_places_the_vehicles_of_that_link(tmp_path: Path) -> None:
    """A run of several links logs each link apart (traffic.tlog, traffic-c2.tlog): a system id that
    both links use names the vehicle of the log's link."""
    from views_helpers import position_msg

    from fleetctl.mavlink.tlog import tlog_record
    from fleetctl.mission.links import link_tlogs
    from fleetctl.views.replay import read_telemetry_logs

    m = two_links_sharing_sysid_11(tmp_path, c2_sysid=1)
    assert list(link_tlogs(m).values()) == ["traffic.tlog", "traffic-c2.tlog"]
    for k, (name, sysids) in enumerate((("traffic.tlog", (1, 11, 12)), ("traffic-c2.tlog", (1, 11, 13)))):
        log = b"".join(tlog_record(1000.0 + 2 * j + k, position_msg(sysid, 10.0 * j, 0, 0))
                       for j, sysid in enumerate(sysids))
        (tmp_path / name).write_bytes(log)
    placed = [s.vehicle for s in read_telemetry_logs(tmp_path, m)]
    assert placed == ["c1", "c2", "r1", "r3", "r2", "r4"]
