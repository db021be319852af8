"""The MQTT fleet bus of a run of several teams in one controller (fleetctl.run.teams.bus), on a
real mosquitto: every team publishes under ``P/teams/<carrier>`` as a ``--team`` controller does
(status with its identity, telemetry, events, plan), the run's combined status and journal go to
``P/status`` and ``P/events``, task messages are refused, and a broker that is down changes
nothing in the flight."""

from __future__ import annotations

import asyncio
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import aiomqtt
import pytest

from fleetctl.bus.teams.protocol import TeamState, allocation_hash, parse_status
from fleetctl.journal import read_journal
from fleetctl.run.flight import execute
from fleetctl.run.teams.own_controller import team_shares
from tests.bus.test_bus import MOSQUITTO, WAIT, Broker, Subscriber, free_tcp_port
from tests.run.teams.teams_helpers import mission_from, two_teams

SPEEDUP = 20.0
PREFIX = "test/teamsbus"

pytestmark = pytest.mark.skipif(MOSQUITTO is None, reason="mosquitto binary not installed "
                                "(scripts/test.sh installs Debian's mosquitto)")


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Broker]:
    b = Broker(tmp_path)
    b.start()
    yield b
    b.stop()


def _dicts(sub: Subscriber, topic: str) -> list[dict[str, Any]]:
    return [d for d in sub.on(topic) if isinstance(d, dict)]


def _kinds(sub: Subscriber, topic: str) -> list[str]:
    return [str(e.get("kind")) for e in _dicts(sub, topic)]


async def _retained(port: int, topic: str) -> dict[str, Any]:
    async with aiomqtt.Client("127.0.0.1", port, timeout=5) as c:
        await c.subscribe(topic, qos=1)
        async with asyncio.timeout(10):
            async for msg in c.messages:
                assert isinstance(msg.payload, bytes | bytearray)
                data: dict[str, Any] = json.loads(msg.payload)
                return data
    raise AssertionError(f"no retained message on {topic}")


async def _send_task_add_once_online(broker: Broker, sub: Subscriber) -> None:
    await sub.wait_for(lambda: any(s.get("status") == "online" for s in _dicts(sub, "teams/c1/status")),
                       "team c1 online")
    async with aiomqtt.Client("127.0.0.1", broker.port, timeout=5) as c:
        task = json.dumps({"id": "t9", "position": [0, 10, 3]})
        await c.publish(f"{PREFIX}/teams/c1/tasks/add", task, qos=1)


@pytest.mark.slow
async def test_a_two_team_deploy_in_one_controller_publishes_every_team(broker: Broker,
                                                                       tmp_path: Path) -> None:
    d = two_teams(mqtt={"url": broker.url, "topic_prefix": PREFIX, "accept_task_changes": True})
    m = mission_from(d, tmp_path)
    async with Subscriber(broker.port, PREFIX) as sub:
        poke = asyncio.create_task(_send_task_add_once_online(broker, sub))
        flight = execute(m, "deploy", run_dir=tmp_path / "run", speedup=SPEEDUP)
        out = await asyncio.wait_for(flight, WAIT * 2)
        await asyncio.wait_for(poke, WAIT)
        assert out.exit_code == 0 and out.summary["result"] == "complete", out.summary
        for team in ("c1", "c2"):
            await sub.wait_for(lambda t=team: any(s.get("status") == "done"  # type: ignore[misc]
                                                  for s in _dicts(sub, f"teams/{t}/status")), f"{team} done")
        await sub.wait_for(lambda: any(s.get("status") == "done" for s in _dicts(sub, "status")), "run done")
        await sub.wait_for(lambda: _dicts(sub, "teams/c1/errors") != [], "the refused task message answered")

    s = out.summary
    shares = {t["carrier"]: set(t["deploy"]["tasks_reached"]) for t in s["teams"]}
    sessions = set()
    for team in ("c1", "c2"):
        statuses = _dicts(sub, f"teams/{team}/status")
        assert statuses[0]["status"] == "online" and statuses[-1]["status"] == "done"
        last = statuses[-1]
        assert last["team"] == team and last["vehicles"] == "sim" and last["carrier"]["id"] == team
        sessions.add(last["session"])
        # what a --team controller elsewhere makes of it: a valid status of that team
        peer = parse_status(team, json.dumps(last).encode(), ("c1", "c2"))
        assert peer.state == TeamState.DONE and peer.session == last["session"]
        assert {st["allocation"] for st in statuses} == {_dicts(sub, "teams/c1/status")[0]["allocation"]}
        # telemetry of the team's carrier and rovers under the team's prefix, none of the other team's
        rovers = next(t["rovers"] for t in s["teams"] if t["carrier"] == team)
        for vid in (team, *rovers):
            tel = _dicts(sub, f"teams/{team}/vehicles/{vid}/telemetry")
            assert tel and tel[-1]["id"] == vid, (team, vid)
        other = "c2" if team == "c1" else "c1"
        assert not sub.on(f"teams/{team}/vehicles/{other}/telemetry")
        # the team's own journal on its events, its plan retained
        kinds = _kinds(sub, f"teams/{team}/events")
        reached = {e["task"] for e in _dicts(sub, f"teams/{team}/events") if e.get("kind") == "task_reached"}
        assert reached == shares[team] and "plan" in kinds and "summary" in kinds
        journal = read_journal(Path(next(t["deploy"]["records"] for t in s["teams"] if t["carrier"] == team))
                               / "journal.jsonl")
        assert [r["kind"] for r in journal] == kinds  # every record, in order
        assert _dicts(sub, f"teams/{team}/plan")[-1]["schema"] == "fleetctl.plan/1"
        retained = await _retained(broker.port, f"{PREFIX}/teams/{team}/status")
        assert retained["status"] == "done" and retained["team"] == team
    assert len(sessions) == 2
    # a --team controller's allocation hash is never these teams' (it reports them as team_mismatch)
    assert last["allocation"] != allocation_hash(m.name, team_shares(m))
    assert set(shares["c1"]) | set(shares["c2"]) == {"t1", "t2", "t3", "t4"}
    # no claims or progress: the controller owns the allocation
    assert not [t for _, t, _ in sub.messages if t.startswith("claims/") or t.endswith("/progress")]
    # the refused task message changed nothing
    err = _dicts(sub, "teams/c1/errors")[-1]
    assert "not supported yet in a run of several teams" in err["error"]
    assert "t9" not in s["tasks_reached"] + s["tasks_unserved"]
    # the run's combined status and journal under P
    top = _dicts(sub, "status")
    assert top[0]["status"] == "online" and top[-1]["status"] == "done" and top[-1]["teams"] == ["c1", "c2"]
    top_kinds = _kinds(sub, "events")
    assert "teams_plan" in top_kinds and "bus_connected" in top_kinds and top_kinds[-1] == "summary"
    assert s["mqtt"]["state"] == "connected" and set(s["mqtt"]["teams"]) == {"c1", "c2"}
    assert all(b["state"] == "closed" or b["published"] > 0 for b in s["mqtt"]["teams"].values())


@pytest.mark.slow
async def test_a_broker_that_is_down_changes_nothing_in_a_teams_run(tmp_path: Path) -> None:
    url = f"mqtt://127.0.0.1:{free_tcp_port()}"  # nobody listens there
    m = mission_from(two_teams(mqtt={"url": url, "topic_prefix": PREFIX}), tmp_path)
    out = await asyncio.wait_for(execute(m, "deploy", run_dir=tmp_path / "run", speedup=SPEEDUP), WAIT * 2)
    s = out.summary
    assert out.exit_code == 0 and s["result"] == "complete", s
    assert sorted(s["tasks_reached"]) == ["t1", "t2", "t3", "t4"]
    assert s["mqtt"]["state"] == "reconnecting" and s["mqtt"]["connects"] == 0
    kinds = [r["kind"] for r in read_journal(tmp_path / "run" / "journal.jsonl")]
    assert "bus_reconnecting" in kinds


async def test_an_interrupted_teams_run_says_so_and_closes_every_bus(broker: Broker, tmp_path: Path) -> None:
    m = mission_from(two_teams(mqtt={"url": broker.url, "topic_prefix": PREFIX}), tmp_path)
    async with Subscriber(broker.port, PREFIX) as sub:
        task = asyncio.create_task(execute(m, "deploy", run_dir=tmp_path / "run", speedup=SPEEDUP))
        await sub.wait_for(lambda: "rover_launched" in _kinds(sub, "teams/c2/events"), "c2 launched a rover")
        task.cancel()
        out = await asyncio.wait_for(task, WAIT)
        assert out.exit_code == 130 and out.summary["result"] == "interrupted"
        for topic in ("status", "teams/c1/status", "teams/c2/status"):
            await sub.wait_for(lambda t=topic: any(s.get("status") == "interrupted"  # type: ignore[misc]
                                                   for s in _dicts(sub, t)), f"{topic} interrupted")
    left = [t.get_name() for t in asyncio.all_tasks() if t.get_name().startswith("mqtt")]
    assert left == []  # every bus task of the run ended with it
    for team in ("c1", "c2"):  # each team's records say where its bus stood when its run began
        records = tmp_path / "run" / "teams" / team / "deploy"
        own = [r["kind"] for r in read_journal(records / "journal.jsonl")]
        assert "bus_connected" in own
