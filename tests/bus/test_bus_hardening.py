"""The MQTT bus survives every payload and guards who may change a mission.

Without a broker: FleetBus.handle_task_message on its own (each message its own error boundary,
size and depth limits, off unless the mission enables it, absurd changes refused unless forced,
changes before the controller exists queued). With a real mosquitto (tests/bus/test_bus.py's
Broker): a fuzzed payload stream against a running bus, after which telemetry still flows and a
valid change still arrives; and a broker with password_file + ACL (the README's config), where
only the named operator can change tasks.
"""

from __future__ import annotations

import asyncio
import json
import random
import subprocess
import time
from pathlib import Path
from typing import Any

import aiomqtt
import pytest

from fleetctl.bus.client import FleetBus, bus_config  # noqa: E402
from fleetctl.mission import Mission  # noqa: E402
from fleetctl.mission.model import TaskWork
from fleetctl.run.state import FleetState  # noqa: E402
from tests.bus.test_bus import MOSQUITTO, WAIT, Broker, Subscriber, free_tcp_port  # noqa: E402
from tests.run.ctl_helpers import mission_dict, mission_from


class FakeExecutor:
    def __init__(self) -> None:
        self.changes: list[tuple[list[str], list[str], str]] = []
        self.work: dict[str, TaskWork] = {}
        self.retime: dict[str, TaskWork] = {}

    def submit_task_change(self, add: list[Any], remove: list[str], source: str,
                           work: dict[str, TaskWork] | None = None,
                           retime: dict[str, TaskWork] | None = None) -> None:
        self.changes.append(([t.id for t in add], list(remove), source))
        self.work.update(work or {})
        self.retime.update(retime or {})


def make_mission(tmp_path: Path, port: int = 1883, prefix: str = "test/hard", accept: bool = True,
                 rovers: int = 3, **mqtt: Any) -> Mission:
    d = mission_dict(rovers=rovers)
    d["mqtt"] = {"url": f"mqtt://127.0.0.1:{port}", "topic_prefix": prefix, **mqtt}
    if accept:
        d["mqtt"]["accept_task_changes"] = True
    return mission_from(d, tmp_path)


def make_bus(mission: Mission) -> tuple[FleetBus, list[dict[str, Any]], list[tuple[str, dict[str, Any]]]]:
    cfg = bus_config(mission)
    assert cfg is not None
    bus = FleetBus(cfg, mission)
    errors: list[dict[str, Any]] = []
    records: list[tuple[str, dict[str, Any]]] = []
    orig = bus.publish

    def publish(suffix: str, payload: Any, **kw: Any) -> None:
        if suffix == "errors":
            errors.append(payload)
        orig(suffix, payload, **kw)

    bus.publish = publish  # type: ignore[method-assign]
    bus.record = lambda kind, **data: records.append((kind, data))
    return bus, errors, records


ADD = "test/hard/tasks/add"
REMOVE = "test/hard/tasks/remove"


def msg(data: Any) -> bytes:
    return json.dumps(data).encode()


# ------------------------------------------------------------------------------------ no broker


def test_task_changes_are_off_by_default(tmp_path: Path) -> None:
    bus, errors, _ = make_bus(make_mission(tmp_path, accept=False))
    bus.attach_executor(ex := FakeExecutor())
    assert not bus.handle_task_message(ADD, msg({"tasks": [{"id": "t9", "position": [5, 5, 2]}]}))
    assert not bus.handle_task_message(REMOVE, msg({"tasks": ["t1"]}))
    assert not ex.changes and bus.rejected == 2
    assert "accept_task_changes: true" in errors[0]["error"] and "docs/mqtt.md" in errors[0]["error"]


@pytest.mark.parametrize("payload", [
    b'{"tasks":[{"id":["x"],"position":[1,1,0]}]}',  # an unhashable id (stopped the bus before)
    b"[" * 30_000 + b"]" * 30_000,  # RecursionError in json.loads before
    b'{"tasks":[{"id":"t9","position":[1e400,1,0]}]}',
    b'{"tasks":[{"id":"t9","position":[' + b"9" * 5000 + b',1,0]}]}',  # over int str digits
    b'{"tasks":[{"id":"t9","position":[' + b"9" * 400 + b',1,0]}]}',
    b'{"tasks":[{"id":"t9","position":{"x":1}}]}', b'{"tasks":{"id":"t9"}}', b"null", b"[]", b"7", b'"x"',
    b'{"tasks":[null]}', b'{"tasks":[["t9"]]}', b"\xff\xfe", b"", b'{"force":"yes","tasks":[]}',
    b'{"tasks":[{"id":"t9","position":[1,1,0],"extra":{"a":{"b":{"c":[[[[[[[[[[[[[[[[[1]]]]]]]]]]]]]]]]]}}}}]}',
    b"x" * 70_000,
])
def test_bad_payloads_are_answered_and_change_nothing(tmp_path: Path, payload: bytes) -> None:
    bus, errors, records = make_bus(make_mission(tmp_path))
    bus.attach_executor(ex := FakeExecutor())
    assert bus.handle_task_message(ADD, payload) is False
    assert bus.handle_task_message(REMOVE, payload) is False
    assert not ex.changes and bus.rejected == 2 and len(errors) == 2
    assert all(isinstance(e["error"], str) and e["error"] for e in errors)
    assert [k for k, _ in records] == ["bus_rejected", "bus_rejected"]
    # and the next valid message still works
    assert bus.handle_task_message(ADD, msg({"tasks": [{"id": "t9", "position": [5, 5, 2]}]}))
    assert ex.changes == [(["t9"], [], f"mqtt:{ADD}")]


def test_far_task_is_refused_unless_forced(tmp_path: Path) -> None:
    bus, errors, records = make_bus(make_mission(tmp_path))
    bus.attach_executor(ex := FakeExecutor())
    far = {"id": "t9", "position": [28_000, 0, 2]}
    assert not bus.handle_task_message(ADD, msg({"tasks": [far]}))
    assert "more than 2 x the mission's extent" in errors[-1]["error"]
    assert '"force": true' in errors[-1]["error"]
    assert bus.handle_task_message(ADD, msg({"tasks": [far], "force": True}))
    assert ex.changes[-1][0] == ["t9"] and records[-1][1].get("force") is True


def test_a_task_added_keeps_each_rover_on_its_own_link(tmp_path: Path) -> None:
    """Rovers with links of their own may reuse system ids: the task set re-checked with a new
    task keeps every rover on its link (not all of them on the carrier's, where the ids clash)."""
    units = [{"id": "r1", "sysid": 11}, {"id": "r2", "sysid": 11, "connection": "sim"},
             {"id": "r3", "sysid": 12}]
    d = mission_dict(units=units)
    d["mqtt"] = {"url": "mqtt://127.0.0.1:1883", "topic_prefix": "test/hard", "accept_task_changes": True}
    bus, errors, _ = make_bus(mission_from(d, tmp_path))
    bus.attach_executor(ex := FakeExecutor())
    assert bus.handle_task_message(ADD, msg({"tasks": [{"id": "t9", "position": [60, 30, 2]}]})), errors
    assert ex.changes[-1][0] == ["t9"]


def test_task_near_the_others_is_accepted(tmp_path: Path) -> None:
    bus, _, _ = make_bus(make_mission(tmp_path))
    bus.attach_executor(ex := FakeExecutor())
    assert bus.handle_task_message(ADD, msg({"tasks": [{"id": "t9", "position": [60, 30, 2]}]}))
    assert ex.changes


def test_removing_every_task_is_refused_unless_forced(tmp_path: Path) -> None:
    bus, errors, _ = make_bus(make_mission(tmp_path))
    bus.attach_executor(ex := FakeExecutor())
    assert bus.handle_task_message(REMOVE, msg({"tasks": ["t1"]}))
    assert not bus.handle_task_message(REMOVE, msg({"tasks": ["t2"]}))
    assert "remove every task" in errors[-1]["error"]
    assert bus.handle_task_message(REMOVE, msg({"tasks": ["t2"], "force": True}))
    assert [c[1] for c in ex.changes] == [["t1"], ["t2"]]


def test_changes_before_the_controller_are_queued(tmp_path: Path) -> None:
    bus, _, records = make_bus(make_mission(tmp_path))
    assert bus.handle_task_message(ADD, msg({"tasks": [{"id": "t9", "position": [5, 5, 2]}]}))
    assert not bus.handle_task_message(ADD, msg({"tasks": [{"id": "t9", "position": [6, 5, 2]}]}))  # dup
    assert records[0][1].get("queued") is True
    bus.attach_executor(ex := FakeExecutor())
    assert ex.changes == [(["t9"], [], f"mqtt:{ADD}")]


def test_an_added_task_carries_its_duration_and_work_mode(tmp_path: Path) -> None:
    mission = make_mission(tmp_path, rovers=6)
    bus, errors, _ = make_bus(mission)
    assert bus.handle_task_message(ADD, msg({"tasks": [{"id": "t8", "position": [5, 5, 2], "duration": 45}]}))
    bus.attach_executor(ex := FakeExecutor())  # a queued change keeps its work
    assert bus.handle_task_message(ADD, msg({"tasks": [{"id": "t9", "position": [6, 5, 0], "work": "ground"},
                                                       {"id": "t10", "position": [7, 5, 2]}]})), errors
    assert ex.work["t8"] == TaskWork(45.0, ground=mission.rovers.work == "ground")
    assert ex.work["t9"] == TaskWork(mission.dwell, ground=True)
    assert ex.work["t10"] == mission.task_work("t10")  # none given: the mission's dwell and rovers.work


UPDATE = "test/hard/tasks/update"


def make_operation(tmp_path: Path) -> Mission:
    d = mission_dict(rovers=2)
    d["operation"] = True
    d["carrier"]["swap_time"] = 10.0
    d["tasks"] = [{"id": "t1", "position": [20, 10, 3], "duration": 30},
                  {"id": "t2", "position": [30, 10, 0], "duration": 20, "work": "ground"},
                  {"id": "t3", "position": [40, 10, 3]}]
    d["mqtt"] = {"url": "mqtt://127.0.0.1:1883", "topic_prefix": "test/hard", "accept_task_changes": True}
    return mission_from(d, tmp_path)


def test_an_operation_task_s_work_is_changed_over_mqtt(tmp_path: Path) -> None:
    mission = make_operation(tmp_path)
    bus, errors, records = make_bus(mission)
    assert bus.handle_task_message(UPDATE, msg({"tasks": [{"id": "t1", "duration": 75}]})), errors
    bus.attach_executor(ex := FakeExecutor())  # a queued change keeps its new work
    both = [{"id": "t2", "work": "hover"}, {"id": "t3", "duration": 12, "work": "ground"}]
    assert bus.handle_task_message(UPDATE, msg({"tasks": both})), errors
    assert ex.retime == {"t1": TaskWork(75.0, ground=False), "t2": TaskWork(20.0, ground=False),
                         "t3": TaskWork(12.0, ground=True)}  # what a message does not give stays
    assert [c[:2] for c in ex.changes] == [([], []), ([], [])]
    updates = [d["update"] for k, d in records if k == "bus_task_change" and "update" in d]
    assert updates == [["t1"], ["t2", "t3"]]


@pytest.mark.parametrize(("update", "why"), [
    ({"id": "t9", "duration": 10}, "unknown task"), ({"id": "t1"}, "duration"),
    ({"id": "t1", "position": [1, 1, 1]}, "nothing else"),
    ({"id": "t1", "duration": -5}, "tasks[0].duration"), ({"id": "t1", "work": "swimming"}, "tasks[0].work")])
def test_a_bad_task_update_is_refused(tmp_path: Path, update: dict[str, Any], why: str) -> None:
    bus, errors, _ = make_bus(make_operation(tmp_path))
    bus.attach_executor(ex := FakeExecutor())
    assert not bus.handle_task_message(UPDATE, msg({"tasks": [update]}))
    assert ex.changes == [] and why in errors[-1]["error"], errors


def test_a_task_update_is_refused_outside_an_operation(tmp_path: Path) -> None:
    bus, errors, _ = make_bus(make_mission(tmp_path))
    bus.attach_executor(ex := FakeExecutor())
    assert not bus.handle_task_message(UPDATE, msg({"tasks": [{"id": "t1", "duration": 10}]}))
    assert ex.changes == [] and "long operation" in errors[-1]["error"]


@pytest.mark.parametrize("bad", [{"duration": -1}, {"duration": "long"}, {"duration": 1e9},
                                 {"work": "swimming"}, {"duration": True}])
def test_a_bad_duration_or_work_mode_is_refused(tmp_path: Path, bad: dict[str, Any]) -> None:
    bus, errors, _ = make_bus(make_mission(tmp_path))
    bus.attach_executor(ex := FakeExecutor())
    assert not bus.handle_task_message(ADD, msg({"tasks": [{"id": "t9", "position": [5, 5, 2]} | bad]}))
    assert ex.changes == [] and "tasks[0]." + next(iter(bad)) in errors[-1]["error"]


def test_bus_task_end_is_reported(tmp_path: Path) -> None:
    mission = make_mission(tmp_path)
    bus, _, records = make_bus(mission)
    state = FleetState(mission, max_events=50)
    bus.state = state

    async def boom() -> None:
        raise RuntimeError("bug")

    async def run(name: str) -> None:
        t = asyncio.create_task(boom(), name=name)
        t.add_done_callback(bus._on_run_done)
        await asyncio.sleep(0.01)

    asyncio.run(run("mqtt telemetry"))
    assert bus.status != "failed" and ("bus_telemetry_failed", {"error": "RuntimeError: bug"}) in records
    asyncio.run(run("mqtt bus"))
    assert bus.status == "failed" and "RuntimeError: bug" in (bus.failed or "")
    assert any(e.kind == "bus_failed" for e in state.events)
    assert ("bus_failed", {"error": "RuntimeError: bug"}) in records


# ------------------------------------------------------------------------------------ a real broker

needs_broker = pytest.mark.skipif(MOSQUITTO is None, reason="mosquitto binary not installed")


def fuzz_payloads(seed: int, n: int) -> list[bytes]:
    rng = random.Random(seed)
    good = msg({"tasks": [{"id": "t9", "position": [5, 5, 2]}]})
    out = []
    for _ in range(n):
        k = rng.randrange(6)
        if k == 0:
            out.append(bytes(rng.randrange(256) for _ in range(rng.randint(0, 300))))
        elif k == 1:  # truncated
            out.append(good[:rng.randrange(len(good))])
        elif k == 2:  # bit flips
            b = bytearray(good)
            for _ in range(rng.randint(1, 4)):
                b[rng.randrange(len(b))] ^= 1 << rng.randrange(8)
            out.append(bytes(b))
        elif k == 3:  # deep
            d = rng.choice([20, 1000, 30_000])
            out.append(b"[" * d + b"]" * d)
        elif k == 4:  # type flips
            v = rng.choice([None, True, 1e308, -1, "x", [], {}, ["t9"], 10**30])
            out.append(msg({"tasks": [{"id": v, "position": [5, 5, 2]}]}) if rng.random() < 0.5
                       else msg({"tasks": [{"id": "t9", "position": [v, 5, 2]}]}))
        else:  # huge
            out.append(b'{"tasks":"' + b"a" * rng.choice([1000, 70_000]) + b'"}')
    return out


class OutSubscriber(Subscriber):
    """Collects what the controller publishes (not the fuzzed task topics: their payloads are junk)."""

    async def _run(self) -> None:
        while True:
            try:
                async with aiomqtt.Client("127.0.0.1", self.port, timeout=5) as client:
                    for topic in ("status", "errors", "vehicles/+/telemetry"):
                        await client.subscribe(f"{self.prefix}/{topic}", qos=1)
                    self.ready.set()
                    async for m in client.messages:
                        raw = bytes(m.payload) if isinstance(m.payload, bytes | bytearray) else b""
                        self.messages.append((time.monotonic(), m.topic.value[len(self.prefix) + 1:],
                                              json.loads(raw)))
            except aiomqtt.MqttError:
                await asyncio.sleep(0.2)


async def _run_bus(mission: Mission) -> tuple[FleetBus, FakeExecutor, FleetState]:
    cfg = bus_config(mission)
    assert cfg is not None
    bus = FleetBus(cfg, mission)
    state = FleetState(mission, max_events=200)
    ex = FakeExecutor()
    bus.start(state, lambda kind, **data: None)
    bus.attach_executor(ex)
    deadline = time.monotonic() + WAIT
    while bus.status != "connected":
        assert time.monotonic() < deadline, "the bus did not connect"
        await asyncio.sleep(0.05)
    return bus, ex, state


@needs_broker
async def test_fuzzed_payloads_against_a_running_bus(tmp_path: Path) -> None:
    broker = Broker(tmp_path)
    broker.start()
    prefix = "test/hard"
    try:
        mission = make_mission(tmp_path, broker.port, prefix, rovers=8)  # rovers to spare for accepted adds
        bus, ex, _ = await _run_bus(mission)
        payloads = fuzz_payloads(13, 150)
        async with OutSubscriber(broker.port, prefix) as sub:
            async with aiomqtt.Client("127.0.0.1", broker.port, timeout=5) as c:
                for i, p in enumerate(payloads):
                    await c.publish(f"{prefix}/tasks/{'add' if i % 3 else 'remove'}", p, qos=1)
            await sub.wait_for(lambda: bus.rejected + len(ex.changes) >= len(payloads),
                               "every payload handled")
            assert bus.status == "connected" and not bus.failed
            # the bus still works: telemetry flows and a valid change arrives
            since = time.monotonic()
            await sub.wait_for(lambda: sub.on("vehicles/r1/telemetry", since=since),
                               "telemetry after the fuzz")
            n = len(ex.changes)
            async with aiomqtt.Client("127.0.0.1", broker.port, timeout=5) as c:
                await c.publish(f"{prefix}/tasks/add", msg({"tasks": [{"id": "t77", "position": [7, 7, 2]}]}),
                                qos=1)
            await sub.wait_for(lambda: len(ex.changes) > n,
                               f"the valid change (errors: {sub.on('errors')[-2:]})")
            assert ex.changes[-1][0] == ["t77"]
            # every rejection is answered; under load the answers may still be queued behind the
            # change, so wait for them rather than count them at once
            await sub.wait_for(lambda: len(sub.on("errors")) >= bus.rejected,
                               "an answer on errors for each rejected payload")
            assert bus.dropped == 0
        await bus.aclose("done")
        async with aiomqtt.Client("127.0.0.1", broker.port, timeout=5) as c:  # retained final status
            await c.subscribe(f"{prefix}/status", qos=1)
            async with asyncio.timeout(WAIT):
                async for m in c.messages:
                    assert json.loads(bytes(m.payload))["status"] == "done"  # type: ignore[arg-type]
                    break
    finally:
        broker.stop()


ACL_USERS = {"fleetctl": "ctl-pass", "operator": "op-pass", "viewer": "view-pass"}


def secured_broker(tmp_path: Path, prefix: str) -> Broker:
    """mosquitto with authentication and the README's ACL: only 'operator' may publish task changes."""
    pw = tmp_path / "passwd"
    pw.write_text("", encoding="utf-8")
    for user, password in ACL_USERS.items():
        subprocess.run(["mosquitto_passwd", "-b", str(pw), user, password], check=True, capture_output=True)
    acl = tmp_path / "acl"
    acl.write_text(f"user fleetctl\ntopic readwrite {prefix}/#\n\n"
                   f"user operator\ntopic read {prefix}/#\ntopic write {prefix}/tasks/#\n\n"
                   f"user viewer\ntopic read {prefix}/#\n", encoding="utf-8")
    broker = Broker(tmp_path)
    # 'user root': run as root (CI), mosquitto would drop to user 'mosquitto', which cannot read the
    # files in pytest's private tmp dir; the README's config leaves that option out
    broker.conf.write_text(f"listener {broker.port} 127.0.0.1\nallow_anonymous false\npersistence false\n"
                           f"password_file {pw}\nacl_file {acl}\nuser root\n", encoding="utf-8")
    for f in (pw, acl):
        f.chmod(0o644)
    return broker


@needs_broker
@pytest.mark.skipif(subprocess.run(["which", "mosquitto_passwd"], capture_output=True).returncode != 0,
                    reason="mosquitto_passwd not installed")
async def test_only_the_named_operator_can_change_tasks(tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    prefix = "test/acl"
    broker = secured_broker(tmp_path, prefix)
    broker.start()
    monkeypatch.setenv("FLEETCTL_TEST_CTL_PASSWORD", ACL_USERS["fleetctl"])
    try:
        mission = make_mission(tmp_path, broker.port, prefix, username="fleetctl",
                               password_env="FLEETCTL_TEST_CTL_PASSWORD")
        bus, ex, _ = await _run_bus(mission)
        add = msg({"tasks": [{"id": "t9", "position": [5, 5, 2]}]})
        with pytest.raises(aiomqtt.MqttError):  # anonymous: refused at connect
            async with aiomqtt.Client("127.0.0.1", broker.port, timeout=5) as c:
                await c.publish(f"{prefix}/tasks/add", add, qos=1)
        async with aiomqtt.Client("127.0.0.1", broker.port, username="viewer", password=ACL_USERS["viewer"],
                                  timeout=5) as c:
            await c.publish(f"{prefix}/tasks/add", add, qos=1)  # dropped by the broker's ACL
            await c.publish(f"{prefix}/tasks/remove", msg({"tasks": ["t1"]}), qos=1)
        async with aiomqtt.Client("127.0.0.1", broker.port, username="operator",
                                  password=ACL_USERS["operator"], timeout=5) as c:
            await c.publish(f"{prefix}/tasks/add", add, qos=1)
        deadline = time.monotonic() + WAIT
        while not ex.changes:
            assert time.monotonic() < deadline, "the operator's change did not arrive"
            await asyncio.sleep(0.05)
        await asyncio.sleep(0.3)
        assert ex.changes == [(["t9"], [], f"mqtt:{prefix}/tasks/add")]  # the viewer's never arrived
        assert bus.rejected == 0
        await bus.aclose("done")
    finally:
        broker.stop()


def test_free_port_helper_is_shared() -> None:
    assert 0 < free_tcp_port() < 65536
