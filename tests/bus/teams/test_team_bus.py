"""The team coordination protocol (fleetctl.bus.teams, fleetctl.run.teams.link).

The board's rules without I/O (conflict rule, stale sessions, orphans, a deterministic split),
then team links on a real mosquitto: a peer process that is SIGKILLed is seen offline through its
last will and its tasks are claimed; bad coordination messages are ignored and journaled; a
better claim takes a task, a worse one is answered; claims made while the broker is away go out
when it is back.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import aiomqtt
import pytest

from fleetctl.bus.client import FleetBus, bus_config
from fleetctl.bus.teams.board import HANDOVER_GRACE, ClaimBoard
from fleetctl.bus.teams.protocol import (
    Claim,
    ClaimState,
    ProgressMsg,
    StatusMsg,
    TeamState,
    Topics,
    parse_claim,
)
from fleetctl.mission import Mission, load_mission
from fleetctl.mission.teams import team_mission
from fleetctl.run.state import FleetState
from fleetctl.run.teams.link import TeamLink
from fleetctl.run.teams.own_controller import team_bus_config, team_shares
from tests.bus.test_bus import MOSQUITTO, Broker
from tests.run.teams.test_team_processes import ROOT, two_team_mission

WAIT = 30.0
ORDER = ("c1", "c2", "c3")
TASKS = ("a", "b", "c", "d")


def board(me: str = "c1", **kw: Any) -> ClaimBoard:
    alloc = {"a": "c1", "b": "c2", "c": "c3", "d": "c3"}
    return ClaimBoard(me, f"s-{me}", ORDER, TASKS, alloc, "h", **kw)


def status(team: str, state: TeamState, session: str | None = None, vehicles: str = "sim") -> StatusMsg:
    return StatusMsg(team, state, session or f"s-{team}", "h", vehicles, False, None, 1.0)


def progress(team: str, reached: set[str] = frozenset(), flying: set[str] = frozenset(),  # type: ignore[assignment]
             pooled: set[str] = frozenset(), free: int = 4) -> ProgressMsg:  # type: ignore[assignment]
    return ProgressMsg(team, f"s-{team}", frozenset(reached), frozenset(flying), frozenset(pooled), free, 1.0)


# -- the rules, no I/O ---------------------------------------------------------------------------------
def test_conflict_rule_epoch_then_team_order_and_stale_sessions() -> None:
    b = board()
    for t in ("c2", "c3"):
        b.on_status(status(t, TeamState.ONLINE), 0.0)
    assert b.owner("c") == ("c3", 0)  # no claim: the allocation's
    b.on_claim(Claim("c", "c2", "s-c2", 1, 5.0), 0.0)
    b.on_claim(Claim("c", "c3", "s-c3", 0, 6.0), 0.0)
    assert b.owner("c") == ("c2", 1)  # the higher epoch
    b.on_claim(Claim("c", "c1", "s-c1", 1, 7.0), 0.0)
    assert b.owner("c") == ("c1", 1)  # same epoch: the team earlier in carriers:
    b.on_claim(Claim("d", "c2", "old-run", 9, 1.0), 0.0)
    assert b.owner("d") == ("c3", 0)  # a claim of an earlier session counts for nothing
    b.on_status(status("c2", TeamState.ONLINE, session="old-run"), 0.0)
    assert b.owner("d") == ("c2", 9)  # ... it does once that session is c2's current one


def test_orphans_need_a_gone_owner_the_grace_and_no_reach() -> None:
    b = board()
    b.on_status(status("c2", TeamState.ONLINE), 0.0)
    b.on_status(status("c3", TeamState.ONLINE, vehicles="real"), 0.0)
    b.on_progress(progress("c3", reached={"c"}, flying={"d"}))
    assert b.orphans(100.0) == []
    b.on_status(status("c3", TeamState.OFFLINE, vehicles="real"), 10.0)
    assert b.orphans(10.0 + HANDOVER_GRACE / 2) == []  # within the grace
    # c reached; d has a real rover flying to it (it flies on): nothing to hand over
    assert b.orphans(10.0 + HANDOVER_GRACE) == []
    b.peers["c3"].vehicles = "sim"  # its vehicles died with it: d is handed over
    assert b.orphans(10.0 + HANDOVER_GRACE) == [("d", 0)]
    b.on_claim(Claim("d", "c3", "s-c3", 2, 1.0), 0.0)
    assert b.orphans(20.0) == [("d", 2)]  # at the epoch it held the task


def test_a_gone_status_left_by_an_earlier_run_hands_nothing_over() -> None:
    b = board()
    b.on_status(status("c3", TeamState.FAILED, session="earlier"), 0.0)  # retained from a former run
    assert not b.peers["c3"].seen_going and b.orphans(100.0) == []
    b.on_status(status("c3", TeamState.ONLINE, session="now"), 100.0)
    b.on_status(status("c3", TeamState.OFFLINE, session="now"), 101.0)
    assert b.peers["c3"].seen_going and b.orphans(101.0 + HANDOVER_GRACE) == [("c", 0), ("d", 0)]


def test_a_released_task_is_an_orphan_at_once_and_a_lost_carrier_takes_nothing() -> None:
    b = board()
    b.on_status(status("c2", TeamState.ONLINE), 0.0)
    b.on_progress(progress("c2", pooled={"b"}, free=3))
    assert b.orphans(0.0) == [] and b.free_of("c2") == 2
    b.on_claim(Claim("b", "c2", "s-c2", 1, 1.0, released=True), 0.0)
    assert b.orphans(0.0) == [("b", 1)]  # its team is online, but gave it up
    b.peers["c2"].carrier_lost = True
    assert b.free_of("c2") == 0
    b.on_claim(Claim("b", "c1", "s-c1", 2, 2.0), 0.0)
    assert b.orphans(0.0) == [] and b.owner("b") == ("c1", 2)


def test_split_is_the_same_for_every_survivor_and_respects_decks() -> None:
    views = [board("c1"), board("c2")]
    for b in views:
        other = "c2" if b.me == "c1" else "c1"
        b.on_status(status(other, TeamState.ONLINE), 0.0)
        b.on_status(status("c3", TeamState.ONLINE), 0.0)
        b.on_status(status("c3", TeamState.OFFLINE), 0.0)
        b.peers["c1"].carrier_xy, b.peers["c2"].carrier_xy = (0.0, 0.0), (100.0, 0.0)
    targets = {"c": (90.0, 0.0, 5.0), "d": (10.0, 0.0, 5.0)}
    for b in views:
        b.targets = targets
        b.carriers = {t: _spec() for t in ORDER}
    free = {"c1": 3, "c2": 3}
    splits = [b.split(b.orphans(10.0), free) for b in views]
    assert splits[0] == splits[1] == {"c": "c2", "d": "c1"}
    assert views[0].split(views[0].orphans(10.0), {"c1": 3, "c2": 0}) == {"c": "c1", "d": "c1"}
    assert views[0].split(views[0].orphans(10.0), {"c1": 1, "c2": 0}) == {"c": "c1"}  # deck full


def _spec() -> Any:
    from planners.core.problem import CarrierSpec

    return CarrierSpec(max_speed=5.0, accel=None, turn_rate=None, unload_time=1.0, load_time=1.0)


def test_claims_settle_held_or_lost() -> None:
    b = board()
    b.on_status(status("c2", TeamState.ONLINE), 0.0)
    mine = b.make_claim("b", 1, 10.0, now=0.0)
    assert b.settle(0.0) == ([], [])  # not back from the broker yet
    b.on_claim(mine, 1.0)
    assert b.settle(1.1) == ([], [])  # back, settling
    assert b.settle(2.0) == (["b"], [])
    assert b.mine["b"].state == ClaimState.HELD
    b.on_claim(Claim("b", "c2", "s-c2", 2, 11.0), 2.0)
    assert b.settle(2.1) == ([], ["b"])


# -- on a real broker -------------------------------------------------------------------------------------
pytestmark_broker = pytest.mark.skipif(MOSQUITTO is None, reason="mosquitto binary not installed")


class Link:
    """A team link on a FleetBus (no executor: held hand-overs wait in ``_undelivered``)."""

    def __init__(self, full: Mission, team: str, shares: dict[str, list[str]]) -> None:
        own = team_mission(full, team, tasks=shares[team])
        config = team_bus_config(bus_config(full), team)
        assert config is not None
        self.bus = FleetBus(config, own)
        self.state = FleetState(own)
        self.records: list[tuple[str, dict[str, Any]]] = []
        self.link = TeamLink(full, team, shares, bus_config(full).topic_prefix,  # type: ignore[union-attr]
                             "sim", [u.id for u in own.rovers.units])

    def record(self, kind: str, **data: Any) -> None:
        self.records.append((kind, data))

    def kinds(self, kind: str) -> list[dict[str, Any]]:
        return [d for k, d in self.records if k == kind]


@contextlib.asynccontextmanager
async def running(full: Mission, team: str, shares: dict[str, list[str]]) -> AsyncIterator[Link]:
    ln = Link(full, team, shares)
    ln.link.prepare(ln.bus)
    ln.bus.start(ln.state, ln.record)
    ln.link.start(ln.state, ln.record)
    try:
        yield ln
    finally:
        await ln.link.close()
        await ln.bus.aclose()


async def until(pred: Any, what: str) -> None:
    deadline = time.monotonic() + WAIT
    while not pred():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        await asyncio.sleep(0.05)


async def publish(port: int, topic: str, payload: Any, retain: bool = False) -> None:
    data = payload if isinstance(payload, bytes) else json.dumps(payload).encode()
    async with aiomqtt.Client("127.0.0.1", port, timeout=5) as c:
        await c.publish(topic, data, qos=1, retain=retain)


async def retained(port: int, topic: str) -> Any:
    async with aiomqtt.Client("127.0.0.1", port, timeout=5) as c:
        await c.subscribe(topic, qos=1)
        async with asyncio.timeout(5):
            async for msg in c.messages:
                return json.loads(bytes(msg.payload))  # type: ignore[arg-type]


PEER = """
import asyncio, sys
from fleetctl.bus.client import FleetBus, bus_config
from fleetctl.mission import load_mission
from fleetctl.mission.teams import team_mission
from fleetctl.run.state import FleetState
from fleetctl.run.teams.link import TeamLink
from fleetctl.run.teams.own_controller import team_bus_config, team_shares

async def main():
    full = load_mission(sys.argv[1])
    shares = team_shares(full)
    team = sys.argv[2]
    own = team_mission(full, team, tasks=shares[team])
    bus = FleetBus(team_bus_config(bus_config(full), team), own)
    state = FleetState(own)
    rovers = [u.id for u in own.rovers.units]
    link = TeamLink(full, team, shares, bus_config(full).topic_prefix, "sim", rovers)
    link.prepare(bus)
    bus.start(state)
    link.start(state, lambda kind, **d: None)
    print("peer up", flush=True)
    await asyncio.sleep(120)

asyncio.run(main())
"""


def start_peer(path: Path, team: str) -> subprocess.Popen[bytes]:
    """A team link of ``team`` in a process of its own (to be SIGKILLed: its last will)."""
    return subprocess.Popen([sys.executable, "-c", PEER, str(path), team], cwd=ROOT, stdout=subprocess.PIPE,
                            env=dict(os.environ, PYTHONPATH=str(ROOT)))


@pytest.mark.slow
@pytestmark_broker
async def test_a_killed_peer_is_seen_offline_and_its_tasks_are_claimed(tmp_path: Path) -> None:
    broker = Broker(tmp_path)
    broker.start()
    path = two_team_mission(tmp_path / "two.yaml", broker.port, "test/will")
    full = load_mission(path)
    shares = team_shares(full)
    peer = start_peer(path, "c2")
    try:
        async with running(full, "c1", shares) as c1:
            b = c1.link.board
            await until(lambda: b.peers["c2"].state == TeamState.ONLINE
                        and b.peers["c2"].progress is not None, "c2 online with its progress")
            assert b.owner("t3")[0] == "c2"
            peer.send_signal(signal.SIGKILL)
            killed = time.monotonic()
            await until(lambda: b.peers["c2"].state == TeamState.OFFLINE, "c2's last will")
            seen = time.monotonic() - killed
            await until(lambda: sorted(c1.link._undelivered) == sorted(shares["c2"]), "c2's tasks held by c1")
            held = time.monotonic() - killed
            assert [d["task"] for d in c1.kinds("team_claim") if d["op"] == "claimed"] == shares["c2"]
            assert all(b.owner(t) == ("c1", 1) for t in shares["c2"])
            assert any(d.get("state") == "offline" for d in c1.kinds("team_peer")) or any(
                e.kind == "team_peer" and e.data.get("state") == "offline" for e in c1.state.events)
            claim = await retained(broker.port, Topics("test/will").claim(shares["c2"][0]))
            assert claim["team"] == "c1" and claim["epoch"] == 1
            print(f"\nlast will seen after {seen:.2f} s, c2's tasks held by c1 after {held:.2f} s")
    finally:
        peer.kill()
        peer.wait(10)
        broker.stop()


@pytestmark_broker
async def test_bad_coordination_messages_are_ignored_and_journaled(tmp_path: Path) -> None:
    broker = Broker(tmp_path)
    broker.start()
    full = load_mission(two_team_mission(tmp_path / "two.yaml", broker.port, "test/bad"))
    shares = team_shares(full)
    top = Topics("test/bad")
    def claim(task: str, **kw: Any) -> bytes:
        return json.dumps({"task": task, "team": "c2", "session": "s", "epoch": 1, "t": 1} | kw).encode()

    bad: list[tuple[str, bytes]] = [
        (top.claim("t1"), b"not json"),
        (top.claim("t1"), b"[" * 50 + b"]" * 50),
        (top.claim("t1"), claim("t1", session="x" * 20000)),
        (top.claim("t1"), claim("t1", team="c9")),
        (top.claim("t1"), claim("t2")),
        (top.claim("t1"), claim("t1", epoch=-1)),
        (top.claim("nope"), claim("nope")),
        (top.status("c2"), json.dumps({"status": "flying-ish", "team": "c2"}).encode()),
        (top.status("c9"), json.dumps({"status": "online", "team": "c9"}).encode()),
        (top.status("c2"), json.dumps({"status": "online", "team": "c2",
                                       "carrier": {"enu": ["x", 0, 0]}}).encode()),
        (top.progress("c2"), json.dumps({"team": "c2", "session": "s", "reached": ["t99"], "free": 1,
                                         "t": 1}).encode()),
        (top.progress("c2"), json.dumps({"team": "c2", "session": "s", "free": True, "t": 1}).encode()),
    ]
    try:
        async with running(full, "c1", shares) as c1:
            await until(lambda: c1.bus.status == "connected", "connected")
            await asyncio.sleep(0.3)
            for topic, payload in bad:
                await publish(broker.port, topic, payload)
            await until(lambda: c1.link.rejected >= len(bad), f"{len(bad)} rejections")
            await asyncio.sleep(0.3)
            assert c1.link.rejected == len(bad)
            errors = [d["error"] for d in c1.kinds("team_message_rejected")]
            assert len(errors) == len(bad)
            assert any("not JSON" in e for e in errors) and any("nested" in e for e in errors)
            assert any("larger than" in e for e in errors)
            assert any("not one of the mission's" in e for e in errors)
            b = c1.link.board
            assert b.peers["c2"].state == TeamState.UNKNOWN and "c9" not in b.peers
            assert "c2" not in b.claims.get("t1", {}) and b.owner("t1") == ("c1", 0)
    finally:
        broker.stop()


@pytestmark_broker
async def test_better_claim_takes_a_task_and_a_worse_one_is_answered(tmp_path: Path) -> None:
    broker = Broker(tmp_path)
    broker.start()
    full = load_mission(two_team_mission(tmp_path / "two.yaml", broker.port, "test/conflict"))
    shares = team_shares(full)
    top = Topics("test/conflict")
    try:
        async with running(full, "c1", shares) as c1:
            await until(lambda: c1.bus.status == "connected", "connected")
            c2 = {"status": "online", "team": "c2", "session": "S2", "allocation": c1.link.board.alloc_hash}
            await publish(broker.port, top.status("c2"), c2, retain=True)
            await until(lambda: c1.link.board.peers["c2"].session == "S2", "c2's status")
            worse = {"task": "t1", "team": "c2", "session": "S2", "epoch": 0, "t": time.time() + 1}
            await publish(broker.port, top.claim("t1"), worse, retain=True)
            await until(lambda: "c2" in c1.link.board.claims.get("t1", {}), "c2's claim of t1")
            await until(lambda: bool(c1.link.board.answered), "c1 to answer the worse claim")
            await asyncio.sleep(0.5)
            again = await retained(broker.port, top.claim("t1"))
            assert again["team"] == "c1" and again["epoch"] == 0  # the winner's claim is retained again
            better = {"task": "t2", "team": "c2", "session": "S2", "epoch": 1, "t": time.time()}
            await publish(broker.port, top.claim("t2"), better, retain=True)
            await until(lambda: c1.link.board.mine["t2"].state == ClaimState.LOST, "c1's claim of t2 lost")
            assert c1.link.board.owner("t2") == ("c2", 1) and c1.link.board.owner("t1") == ("c1", 0)
            assert [d for d in c1.kinds("team_claim") if d["op"] == "lost"] == [
                {"op": "lost", "task": "t2", "by": "c2"}]
    finally:
        broker.stop()


@pytest.mark.slow
@pytestmark_broker
async def test_a_team_with_another_allocation_is_reported_and_ignored(tmp_path: Path) -> None:
    broker = Broker(tmp_path)
    broker.start()
    full = load_mission(two_team_mission(tmp_path / "two.yaml", broker.port, "test/mismatch"))
    shares = team_shares(full)
    top = Topics("test/mismatch")
    try:
        async with running(full, "c1", shares) as c1:
            await until(lambda: c1.bus.status == "connected", "connected")
            c2 = {"status": "online", "team": "c2", "session": "S2", "allocation": "another-file"}
            await publish(broker.port, top.status("c2"), c2, retain=True)
            await publish(broker.port, top.claim("t1"), {"task": "t1", "team": "c2", "session": "S2",
                                                         "epoch": 5, "t": time.time()}, retain=True)
            await until(lambda: "c2" in c1.link.board.claims.get("t1", {}), "c2's claim")
            b = c1.link.board
            assert b.mismatched == {"c2"} and b.owner("t1") == ("c1", 0)  # its claim counts for nothing
            assert b.online_teams() == ["c1"]  # and nothing is handed to it
            c2["status"] = "offline"
            await publish(broker.port, top.status("c2"), c2, retain=True)
            await asyncio.sleep(HANDOVER_GRACE + 0.5)
            assert b.orphans(time.monotonic()) == [] and not c1.kinds("team_claim")  # nor taken from it
            events = [e for e in c1.state.events if e.kind == "team_mismatch"]
            assert len(events) == 1 and "another allocation" in events[0].text
    finally:
        broker.stop()


@pytestmark_broker
async def test_claims_made_while_the_broker_is_away_go_out_when_it_is_back(tmp_path: Path) -> None:
    broker = Broker(tmp_path)
    full = load_mission(two_team_mission(tmp_path / "two.yaml", broker.port, "test/away"))
    shares = team_shares(full)
    async with running(full, "c1", shares) as c1:  # no broker yet: the link runs, claims are queued
        await until(lambda: c1.bus.status == "reconnecting", "the bus to retry")
        claim = c1.link.board.make_claim("t5", 1, time.time(), time.monotonic())
        c1.link._publish_claim(claim)
        broker.start()
        try:
            await until(lambda: c1.bus.status == "connected", "connected")
            got = await retained(broker.port, Topics("test/away").claim("t5"))
            assert got == claim.payload()
            await until(lambda: c1.link.board.mine["t5"].state == ClaimState.HELD, "the claim held")
            own = await retained(broker.port, Topics("test/away").claim(shares["c1"][0]))
            assert own["team"] == "c1" and own["epoch"] == 0
        finally:
            broker.stop()


def three_team_mission(path: Path, port: int, prefix: str) -> Path:
    """c3 in the middle with four tasks, two nearer c1 and two nearer c2."""
    import yaml

    carrier = {"connection": "sim", "heading_deg": 0, "max_speed": 4.0, "accel": 5.0, "turn_rate": None,
               "unload_time": 1.0, "load_time": 1.0}
    d = {"name": "threeteams", "origin": {"lat": 47.397742, "lon": 8.545594, "alt": 488.0},
         "carriers": [{"id": f"c{k + 1}", "sysid": k + 1, "position": [x, 0], **carrier,
                       "fleet": {"count": 4, "sysid_start": 11 + 10 * k}}
                      for k, x in enumerate((0, 300, 150))],
         "rovers": {"max_speed": 5.0, "accel": None, "deploy_range": 15.0, "endurance_range": 600.0,
                    "reserve": 0.1},
         "tasks": [{"id": "a1", "position": [0, 30, 5]}, {"id": "b1", "position": [300, 30, 5]},
                   {"id": "m1", "position": [130, 20, 5]}, {"id": "m2", "position": [140, 50, 5]},
                   {"id": "m3", "position": [160, 50, 5]}, {"id": "m4", "position": [170, 20, 5]}],
         "mqtt": {"url": f"mqtt://127.0.0.1:{port}", "topic_prefix": prefix},
         "planner": {"deploy": "lee", "collect": "lee", "seed": 0}}
    path.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
    return path


@pytest.mark.slow
@pytestmark_broker
async def test_two_survivors_split_a_lost_team_without_a_conflict(tmp_path: Path) -> None:
    broker = Broker(tmp_path)
    broker.start()
    path = three_team_mission(tmp_path / "three.yaml", broker.port, "test/three")
    full = load_mission(path)
    shares = team_shares(full)
    assert sorted(shares["c3"]) == ["m1", "m2", "m3", "m4"], shares
    peer = start_peer(path, "c3")
    try:
        async with running(full, "c1", shares) as c1, running(full, "c2", shares) as c2:
            links = (c1.link, c2.link)
            await until(lambda: all(ln.board.peers["c3"].state == TeamState.ONLINE
                                    and ln.board.peers["c3"].progress is not None for ln in links),
                        "c3 online")
            peer.send_signal(signal.SIGKILL)

            def held() -> bool:
                pending = [t for ln in links for t, c in ln.board.mine.items()
                           if c.state == ClaimState.PENDING]
                both = sorted(c1.link._undelivered + c2.link._undelivered)
                return both == sorted(shares["c3"]) and not pending

            await until(held, "c3's tasks held by the survivors")
            await asyncio.sleep(0.5)
    finally:
        peer.kill()
        peer.wait(10)
        broker.stop()
    # the same split in both controllers: each task claimed once, nearest carrier first, no claim lost
    assert sorted(c1.link._undelivered) == ["m1", "m2"] and sorted(c2.link._undelivered) == ["m3", "m4"]
    for ln in (c1, c2):
        assert not [d for d in ln.kinds("team_claim") if d["op"] == "lost"]
        assert sorted(d["task"] for d in ln.kinds("team_claim") if d["op"] == "claimed") == sorted(
            ln.link._undelivered)


def test_claim_payload_round_trip() -> None:
    for c in (Claim("t1", "c2", "abc", 3, 12.5), Claim("t1", "c2", "abc", 4, 13.0, released=True)):
        assert parse_claim("t1", json.dumps(c.payload()).encode(), ("c1", "c2"), frozenset({"t1"})) == c
