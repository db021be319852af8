"""One controller per team: two ``fleetctl deploy --team`` processes on one real mosquitto.

Each process flies its team's share on its own embedded simulated fleet (real MAVLink over UDP)
and coordinates with the other over the bus (docs/mqtt.md#teams). One test SIGKILLs team c2's
controller after its first task is reached: c1 claims c2's unreached tasks and flies them, and
no task is reached by both. The other stops the broker mid-flight: both teams fly on and finish
their shares, and their claims and progress are on the broker again once it is back.

The hand-over time (c2 killed -> its tasks claimed by c1) is printed (run with ``-s``), never
asserted against a threshold.
"""

from __future__ import annotations

import asyncio
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.bus.test_bus import MOSQUITTO, Broker, Subscriber

ROOT = Path(__file__).resolve().parents[3]
WAIT = 60.0  # s: generous bound of every wait (never a timing assertion)

pytestmark = [pytest.mark.skipif(MOSQUITTO is None, reason="mosquitto binary not installed "
                                "(scripts/test.sh installs Debian's mosquitto)"), pytest.mark.slow]


def two_team_mission(path: Path, port: int, prefix: str, faults: list[dict[str, Any]] | None = None) -> Path:
    """c1 (6 rovers) near two tasks, c2 (4 rovers) 300 m east with four tasks in a row north."""
    carrier = {"connection": "sim", "heading_deg": 0, "max_speed": 4.0, "accel": 5.0, "turn_rate": None,
               "unload_time": 1.0, "load_time": 1.0}
    d: dict[str, Any] = {
        "name": "twoteams",
        "origin": {"lat": 47.397742, "lon": 8.545594, "alt": 488.0},
        "carriers": [
            {"id": "c1", "sysid": 1, "position": [0, 0], **carrier,
             "fleet": {"count": 6, "sysid_start": 11}},
            {"id": "c2", "sysid": 2, "position": [300, 0], **carrier,
             "fleet": {"count": 4, "sysid_start": 31}},
        ],
        "rovers": {"max_speed": 5.0, "accel": None, "deploy_range": 15.0, "endurance_range": 600.0,
                   "reserve": 0.1},
        "tasks": [{"id": "t1", "position": [0, 40, 5]}, {"id": "t2", "position": [0, 80, 5]},
                  {"id": "t3", "position": [300, 50, 5]}, {"id": "t4", "position": [300, 100, 5]},
                  {"id": "t5", "position": [300, 150, 5]}, {"id": "t6", "position": [300, 200, 5]}],
        "mqtt": {"url": f"mqtt://127.0.0.1:{port}", "topic_prefix": prefix},
        "sim": {"speedup": 10.0, "faults": faults or []},
        "links": {"heartbeat_timeout": 3.0},
        "planner": {"deploy": "lee", "collect": "lee", "seed": 0},
    }
    path.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
    return path


def start_team(mission: Path, team: str, run_dir: Path) -> subprocess.Popen[bytes]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    log = (run_dir.parent / f"{run_dir.name}.log").open("wb")
    return subprocess.Popen([sys.executable, "-m", "fleetctl.cli", "deploy", "--mission", str(mission),
                             "--team", team, "--headless", "--run-dir", str(run_dir)],
                            cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT)


def journal(run_dir: Path) -> list[dict[str, Any]]:
    path = run_dir / "journal.jsonl"
    if not path.exists():
        return []
    out = []
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            out.append(json.loads(line))
        except ValueError:  # a line cut by SIGKILL
            pass
    return out


def reached(run_dir: Path) -> list[str]:
    return [r["task"] for r in journal(run_dir) if r.get("kind") == "task_reached"]


async def wait_exit(proc: subprocess.Popen[bytes], timeout: float) -> int:
    deadline = time.monotonic() + timeout
    while proc.poll() is None:
        if time.monotonic() > deadline:
            proc.kill()
            raise AssertionError(f"controller {proc.args} did not finish within {timeout} s")
        await asyncio.sleep(0.1)
    return proc.returncode


async def wait_until(pred: Any, what: str) -> None:
    deadline = time.monotonic() + WAIT
    while not pred():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        await asyncio.sleep(0.05)


def log_of(run_dir: Path, _team: str = "") -> str:
    return (run_dir.parent / f"{run_dir.name}.log").read_text(errors="replace")[-3000:]


async def test_killed_team_is_handed_over(tmp_path: Path) -> None:
    broker = Broker(tmp_path)
    broker.start()
    prefix = "test/handover"
    mission = two_team_mission(tmp_path / "two.yaml", broker.port, prefix)
    d1, d2 = tmp_path / "runs" / "c1", tmp_path / "runs" / "c2"
    d1.parent.mkdir()
    procs = []
    try:
        async with Subscriber(broker.port, prefix) as sub:
            procs = [start_team(mission, "c1", d1), start_team(mission, "c2", d2)]

            def c2_reached_one() -> bool:
                assert procs[1].poll() is None, log_of(d2, "c2")
                return any(isinstance(p, dict) and p.get("reached") for p in sub.on("teams/c2/progress"))

            await wait_until(c2_reached_one, "c2's first task reached (its progress on the bus)")
            procs[1].send_signal(signal.SIGKILL)
            killed = time.time()
            procs[1].wait(10)
            code = await wait_exit(procs[0], WAIT * 1.5)
            last = [p for p in sub.on("teams/c2/progress") if isinstance(p, dict)][-1]
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
        broker.stop()
    assert code == 0, log_of(d1, "c1")
    # c2's journal may miss its last lines (SIGKILL): what it reached is what it last told the bus
    by_c2, by_c1 = sorted(set(reached(d2)) | set(last["reached"])), reached(d1)
    claims = [r for r in journal(d1) if r.get("kind") == "team_claim" and r.get("op") == "claimed"]
    held = [r for r in journal(d1) if r.get("kind") == "team_claim" and r.get("op") == "held"]
    handed = sorted(r["task"] for r in claims)
    assert {r["from"] for r in claims} == {"c2"}
    assert handed == sorted({"t3", "t4", "t5", "t6"} - set(by_c2)), (by_c2, handed)
    assert sorted(r["task"] for r in held) == handed
    assert not set(by_c1) & set(by_c2), f"reached by both teams: {set(by_c1) & set(by_c2)}"
    assert sorted(by_c1 + by_c2) == ["t1", "t2", "t3", "t4", "t5", "t6"], (by_c1, by_c2)
    summary = json.loads((d1 / "summary.json").read_text())
    assert summary["result"] == "complete" and set(handed) <= set(summary["tasks_reached"])
    team = json.loads((d1 / "team.json").read_text())
    assert sorted(team["handed_over"]) == handed and team["peers"] == {"c2": "offline"}
    claim_s = min(r["claimed_t"] for r in claims) - killed
    held_s = max(r["t"] for r in held) - killed
    print(f"\nhand-over: c2 killed -> c1 claimed {handed} after {claim_s:.2f} s, claims held after "
          f"{held_s:.2f} s; c2 reached {by_c2} before it died, c1 reached {by_c1}")


async def test_a_restarted_team_leaves_the_tasks_taken_over_from_it(tmp_path: Path) -> None:
    broker = Broker(tmp_path)
    broker.start()
    mission = two_team_mission(tmp_path / "two.yaml", broker.port, "test/restarted")
    d1, d2, d2b = (tmp_path / "runs" / n for n in ("c1", "c2", "c2-again"))
    d1.parent.mkdir()
    procs = []
    try:
        procs = [start_team(mission, "c1", d1), start_team(mission, "c2", d2)]
        await wait_until(lambda: any(r.get("kind") == "carrier_started" for r in journal(d2)), "c2 flying")
        procs[1].send_signal(signal.SIGKILL)
        procs[1].wait(10)
        await wait_until(lambda: any(r.get("kind") == "team_claim" and r.get("op") == "held"
                                     for r in journal(d1)), "c1 to hold c2's tasks")
        procs.append(start_team(mission, "c2", d2b))  # the same team's controller, started again
        codes = [await wait_exit(p, WAIT * 1.5) for p in (procs[0], procs[2])]
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
        broker.stop()
    assert codes == [0, 0], (log_of(d1), log_of(d2b))
    taken = {r["task"] for r in journal(d1) if r.get("kind") == "team_claim" and r.get("op") == "held"}
    assert taken and taken <= set(reached(d1))
    assert not taken & set(reached(d2b)), (taken, reached(d2b), log_of(d2b, "c2-again"))
    assert any(r.get("kind") == "team_claim_lost" for r in journal(d2b)), log_of(d2b, "c2-again")


async def test_broker_restart_mid_flight(tmp_path: Path) -> None:
    broker = Broker(tmp_path)
    broker.start()
    prefix = "test/restart"
    mission = two_team_mission(tmp_path / "two.yaml", broker.port, prefix)
    d1, d2 = tmp_path / "runs" / "c1", tmp_path / "runs" / "c2"
    d1.parent.mkdir()
    procs = []
    try:
        async with Subscriber(broker.port, prefix) as sub:
            procs = [start_team(mission, "c1", d1), start_team(mission, "c2", d2)]
            await wait_until(lambda: sub.on("teams/c2/status") and reached(d2) == [] and any(
                r.get("kind") == "carrier_started" for r in journal(d2)), "c2 flying")
            broker.stop()
            await wait_until(lambda: all(any(r.get("kind") == "bus_reconnecting" for r in journal(d))
                                         for d in (d1, d2)), "both controllers to see the broker gone")
            assert all(p.poll() is None for p in procs)
            during = len(reached(d2))
            await asyncio.sleep(1.5)
            back = time.monotonic()
            broker.start()
            codes = [await wait_exit(p, WAIT * 1.5) for p in procs]
            await wait_until(lambda: {m[1].split("/")[-1] for m in sub.messages if m[0] >= back
                                      and m[1].startswith("claims/")} >= {"t1", "t2", "t3", "t4", "t5", "t6"},
                             "every claim on the broker again")
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
        broker.stop()
    assert codes == [0, 0], (log_of(d1, "c1"), log_of(d2, "c2"))
    assert sorted(reached(d1)) == ["t1", "t2"] and sorted(reached(d2)) == ["t3", "t4", "t5", "t6"]
    for d in (d1, d2):
        kinds = [r.get("kind") for r in journal(d)]
        assert "bus_reconnecting" in kinds and kinds.count("bus_connected") >= 2
        assert not [r for r in journal(d) if r.get("kind") == "team_claim"], "no hand-over: nobody was gone"
    progress = [m for m in sub.messages if m[0] >= back and m[1] == "teams/c2/progress"]
    assert progress and sorted(progress[-1][2]["reached"]) == ["t3", "t4", "t5", "t6"]
    print(f"\nbroker restart: c2 had reached {during} task(s) when the broker went; both teams completed")


async def test_team_whose_carrier_is_lost_gives_its_unlaunched_tasks_up(tmp_path: Path) -> None:
    broker = Broker(tmp_path)
    broker.start()
    prefix = "test/carrierlost"
    # c2's carrier link goes for good after its route started (before or after its first stop)
    mission = two_team_mission(tmp_path / "two.yaml", broker.port, prefix,
                               faults=[{"kind": "dropout", "vehicle": "c2", "at": 30.0}])
    d1, d2 = tmp_path / "runs" / "c1", tmp_path / "runs" / "c2"
    d1.parent.mkdir()
    procs = []
    try:
        procs = [start_team(mission, "c1", d1), start_team(mission, "c2", d2)]
        code = await wait_exit(procs[0], WAIT * 1.5)
        await wait_exit(procs[1], WAIT)  # its deployment ends (failed if its carrier was at a stop)
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
        broker.stop()
    assert code == 0, log_of(d1, "c1")
    released = [r for r in journal(d2) if r.get("kind") == "team_release"]
    assert released, log_of(d2, "c2")
    gave, by_c2 = released[0]["tasks"], reached(d2)
    assert sorted(gave + by_c2) == ["t3", "t4", "t5", "t6"], (gave, by_c2)
    claims = [r for r in journal(d1) if r.get("kind") == "team_claim" and r.get("op") == "claimed"]
    assert sorted(r["task"] for r in claims) == sorted(gave) and {r["epoch"] for r in claims} == {2}
    assert not set(by_c2) & set(reached(d1))
    assert sorted(reached(d1) + by_c2) == ["t1", "t2", "t3", "t4", "t5", "t6"]


async def test_team_without_a_bus_flies_its_share_alone(tmp_path: Path) -> None:
    mission = two_team_mission(tmp_path / "two.yaml", 1, "unused")
    d = yaml.safe_load(mission.read_text())
    del d["mqtt"]
    mission.write_text(yaml.safe_dump(d, sort_keys=False))
    run = tmp_path / "runs" / "c2"
    run.parent.mkdir()
    proc = start_team(mission, "c2", run)
    assert await wait_exit(proc, WAIT * 1.5) == 0, log_of(run, "c2")
    log = log_of(run, "c2")
    assert "--team c2 without an MQTT bus" in log and "no coordination" in log
    assert sorted(reached(run)) == ["t3", "t4", "t5", "t6"]
    assert any(r.get("kind") == "team_alone" for r in journal(run))


def test_team_option_errors_are_one_line(tmp_path: Path) -> None:
    mission = two_team_mission(tmp_path / "two.yaml", 1, "unused")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    for argv, text in ((["deploy", "--team", "zz"], "no carrier 'zz' in the mission (carriers: c1, c2)"),
                       (["collect", "--team", "zz"], "no carrier 'zz' in the mission (carriers: c1, c2)")):
        out = subprocess.run([sys.executable, "-m", "fleetctl.cli", *argv[:1], "--mission", str(mission),
                              *argv[1:], "--headless"], cwd=ROOT, env=env, capture_output=True, text=True,
                             timeout=WAIT)
        assert out.returncode == 2 and text in out.stderr, (argv, out.stderr)
        assert "Traceback" not in out.stderr
