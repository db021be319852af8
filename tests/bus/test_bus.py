"""The MQTT fleet bus (fleetctl.bus.client, fleetctl watch) against a real broker (Debian's mosquitto).

A session fixture starts ``mosquitto`` on a free loopback port with a temporary config; the
missions fly on the simulated fleet (real MAVLink over UDP) at 20x. ``scripts/test.sh`` installs
mosquitto when it is missing; without the binary these tests are skipped and say so.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import shutil
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import aiomqtt
import pytest

from fleetctl.bus.client import FleetBus, bus_config  # noqa: E402
from fleetctl.mission import Mission  # noqa: E402
from fleetctl.run.flight import execute
from fleetctl.run.lifecycle import RunOutcome  # noqa: E402
from fleetctl.run.state import FleetState  # noqa: E402
from fleetctl.views.view import View  # noqa: E402
from tests.run.ctl_helpers import mission_dict, mission_from

ROOT = Path(__file__).resolve().parents[2]
MOSQUITTO = shutil.which("mosquitto") or next(
    (p for p in ("/usr/sbin/mosquitto", "/usr/local/sbin/mosquitto") if os.access(p, os.X_OK)), None)
PASSWORD = "s3cret-Pa55-do-not-log"
WAIT = 60.0  # generous upper bound for any wait (s); never a timing assertion

pytestmark = pytest.mark.skipif(MOSQUITTO is None, reason="mosquitto binary not installed "
                                "(scripts/test.sh installs Debian's mosquitto: apt-get install -y mosquitto)")


def free_tcp_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Broker:
    """A mosquitto process on 127.0.0.1:``port`` (stoppable and restartable on the same port)."""

    def __init__(self, workdir: Path, port: int | None = None) -> None:
        self.port = port or free_tcp_port()
        self.conf = workdir / f"mosquitto-{self.port}.conf"
        self.conf.write_text(f"listener {self.port} 127.0.0.1\nallow_anonymous true\npersistence false\n",
                             encoding="utf-8")
        self.conf.chmod(0o644)
        self.log = workdir / f"mosquitto-{self.port}.log"
        self.proc: subprocess.Popen[bytes] | None = None

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    def start(self) -> None:
        assert MOSQUITTO is not None
        with self.log.open("ab") as log:
            self.proc = subprocess.Popen([MOSQUITTO, "-c", str(self.conf)], stdout=log, stderr=log)
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"mosquitto exited: {self.log.read_text(errors='replace')[-2000:]}")
            with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", self.port), 0.2):
                return
            time.sleep(0.05)
        raise RuntimeError(f"mosquitto did not listen on {self.port}: {self.log.read_text(errors='replace')}")

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()  # no clean shutdown: like a broker that dies
            self.proc.wait(10.0)
        self.proc = None


@pytest.fixture(scope="session")
def broker(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Broker]:
    b = Broker(tmp_path_factory.mktemp("mosquitto"))
    b.start()
    yield b
    b.stop()


class Subscriber:
    """Collects every message under a prefix (reconnecting when the broker comes back)."""

    def __init__(self, url_port: int, prefix: str) -> None:
        self.port = url_port
        self.prefix = prefix
        self.messages: list[tuple[float, str, Any]] = []
        self.ready = asyncio.Event()
        self._task: asyncio.Task[None] | None = None

    async def __aenter__(self) -> Subscriber:
        self._task = asyncio.create_task(self._run())
        await asyncio.wait_for(self.ready.wait(), WAIT)
        return self

    async def __aexit__(self, *exc: object) -> None:
        assert self._task is not None
        self._task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await self._task

    async def _run(self) -> None:
        while True:
            try:
                async with aiomqtt.Client("127.0.0.1", self.port, timeout=5) as client:
                    await client.subscribe(f"{self.prefix}/#", qos=1)
                    self.ready.set()
                    async for msg in client.messages:
                        raw = bytes(msg.payload) if isinstance(msg.payload, bytes | bytearray) else b""
                        try:
                            data: Any = json.loads(raw)
                        except ValueError:
                            data = raw.decode(errors="replace")
                        self.messages.append((time.monotonic(), msg.topic.value[len(self.prefix) + 1:], data))
            except aiomqtt.MqttError:
                await asyncio.sleep(0.2)

    def on(self, topic: str, since: float = 0.0) -> list[Any]:
        return [d for t, top, d in self.messages if top == topic and t >= since]

    async def wait_for(self, pred: Any, what: str) -> None:
        deadline = time.monotonic() + WAIT
        while not pred():
            assert time.monotonic() < deadline, f"timed out waiting for {what}; got topics " \
                f"{sorted({top for _, top, _ in self.messages})}"
            await asyncio.sleep(0.05)


class StateProbe(View):
    """Gives the test the run's FleetState (the live view's input)."""

    def __init__(self) -> None:
        self.state: FleetState | None = None

    def start(self, state: FleetState, fleet: Any) -> None:
        self.state = state

    async def stop(self) -> None:
        pass


def bus_mission(tmp_path: Path, port: int, prefix: str, **kw: Any) -> Mission:
    d = mission_dict(**kw)
    d["mqtt"] = {"url": f"mqtt://127.0.0.1:{port}", "topic_prefix": prefix, "username": "operator",
                 "password_env": "FLEETCTL_TEST_MQTT_PASSWORD", "accept_task_changes": True}
    return mission_from(d, tmp_path)


@pytest.fixture(autouse=True)
def _password(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FLEETCTL_TEST_MQTT_PASSWORD", PASSWORD)


def events(sub: Subscriber, kind: str | None = None) -> list[dict[str, Any]]:
    return [e for e in sub.on("events") if isinstance(e, dict) and (kind is None or e.get("kind") == kind)]


async def test_telemetry_events_plan_and_status_arrive(broker: Broker, tmp_path: Path,
                                                       caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level("DEBUG")
    prefix = "test/flow"
    mission = bus_mission(tmp_path, broker.port, prefix)
    async with Subscriber(broker.port, prefix) as sub:
        out = await asyncio.wait_for(execute(mission, "deploy", runs_dir=tmp_path / "runs"), WAIT * 2)
        assert out.exit_code == 0, out.error
        await sub.wait_for(lambda: any(s.get("status") == "done" for s in sub.on("status")
                                       if isinstance(s, dict)), "final status")
    for vid in ("carrier", "r1", "r2"):
        tel = sub.on(f"vehicles/{vid}/telemetry")
        assert tel, vid
        assert tel[-1]["id"] == vid and len(tel[-1]["enu"]) == 3 and "battery_pct" in tel[-1]
    assert sub.on("vehicles/r1/telemetry")[-1]["state"] == "on_task"  # the final snapshot
    assert sub.on("vehicles/carrier/telemetry")[-1]["role"] == "carrier"
    kinds = [e["kind"] for e in events(sub)]
    assert "plan" in kinds and kinds.count("task_reached") == 2 and "summary" in kinds
    summary = events(sub, "summary")[-1]
    assert summary["result"] == "complete"
    plans = sub.on("plan")
    assert plans and plans[-1]["schema"] == "fleetctl.plan/1" and plans[-1]["kind"] == "deploy"
    assert sub.on("status")[0]["status"] == "online"
    # every journal record went out on events, in order
    journal = [json.loads(line) for line in (Path(out.run_dir) / "journal.jsonl").read_text().splitlines()]
    assert [r["kind"] for r in journal] == kinds
    # retained: a late subscriber still gets status and plan
    async with aiomqtt.Client("127.0.0.1", broker.port, timeout=5) as c:
        await c.subscribe(f"{prefix}/status", qos=1)
        await c.subscribe(f"{prefix}/plan", qos=1)
        got = {}
        async with asyncio.timeout(WAIT):
            async for msg in c.messages:
                got[msg.topic.value] = json.loads(bytes(msg.payload))  # type: ignore[arg-type]
                if len(got) == 2:
                    break
    assert got[f"{prefix}/status"]["status"] == "done" and got[f"{prefix}/plan"]["kind"] == "deploy"
    # the password is nowhere: journal, summary, published messages, logs
    for f in Path(out.run_dir).iterdir():
        if f.suffix in (".jsonl", ".json"):
            assert PASSWORD not in f.read_text(), f
    assert PASSWORD not in json.dumps([m[2] for m in sub.messages])
    assert PASSWORD not in caplog.text
    assert PASSWORD not in repr(bus_config(mission))


async def _fly_with(mission: Mission, tmp_path: Path, command: str = "deploy",
                    **kw: Any) -> tuple[asyncio.Task[RunOutcome], StateProbe]:
    probe = StateProbe()
    task = asyncio.create_task(execute(mission, command, runs_dir=tmp_path / "runs", view=probe, **kw))
    return task, probe


async def _publish(port: int, topic: str, payload: bytes | str) -> None:
    async with aiomqtt.Client("127.0.0.1", port, timeout=5) as c:
        await c.publish(topic, payload, qos=1)


async def test_bad_task_messages_are_answered_and_change_nothing(broker: Broker, tmp_path: Path) -> None:
    prefix = "test/bad"
    mission = bus_mission(tmp_path, broker.port, prefix)
    bad = [
        b"{not json",
        json.dumps({"tasks": [{"id": "t9"}]}),  # no position
        json.dumps({"tasks": [{"id": "t9", "position": [5, 5, 99]}]}),  # higher than deploy_range (40 m)
        json.dumps({"tasks": [{"id": "t1", "position": [5, 5, 2]}]}),  # duplicate id
        json.dumps({"tasks": [{"id": "t9", "positon": [5, 5, 2]}]}),  # unknown key
        json.dumps({"tasks": [{"id": "t9", "position": [5, 5, 2]}]}),  # 3 tasks for 2 rovers
    ]
    async with Subscriber(broker.port, prefix) as sub:
        task, _ = await _fly_with(mission, tmp_path)
        await sub.wait_for(lambda: events(sub, "plan"), "the deployment plan")
        for p in bad:
            await _publish(broker.port, f"{prefix}/tasks/add", p)
        await _publish(broker.port, f"{prefix}/tasks/remove", json.dumps({"tasks": ["nope"]}))
        await sub.wait_for(lambda: len(sub.on("errors")) == len(bad) + 1, "an answer to every bad message")
        out = await asyncio.wait_for(task, WAIT * 2)
    errors = [e["error"] for e in sub.on("errors")]
    assert "not JSON" in errors[0]
    assert "tasks[0].position: required key is missing" in errors[1]
    assert "higher than rovers.deploy_range" in errors[2]
    assert "'t1' already exists" in errors[3]
    assert "did you mean 'position'" in errors[4]
    assert "every task needs its own rover" in errors[5]
    assert "unknown task id(s) 'nope'" in errors[6]
    assert all(e["topic"].startswith(prefix + "/tasks/") for e in sub.on("errors"))
    assert out.exit_code == 0 and out.summary["tasks_reached"] == ["t1", "t2"]
    assert len(events(sub, "bus_rejected")) == len(bad) + 1


async def test_task_added_over_mqtt_is_reached(broker: Broker, tmp_path: Path) -> None:
    """A valid task added over MQTT during the deployment goes to Executor.submit_task_change,
    the controller replans, the new plan is published and the task is reached."""
    prefix = "test/add"
    mission = bus_mission(tmp_path, broker.port, prefix, rovers=3)
    new = {"id": "t3", "position": [30, 20, 3]}
    async with Subscriber(broker.port, prefix) as sub:
        task, _ = await _fly_with(mission, tmp_path)
        await sub.wait_for(lambda: events(sub, "plan"), "the deployment plan")
        await _publish(broker.port, f"{prefix}/tasks/add", json.dumps({"tasks": [new]}))
        out = await asyncio.wait_for(task, WAIT * 2)
        await sub.wait_for(lambda: events(sub, "summary"), "the summary")
    assert out.exit_code == 0, out.error
    assert sorted(out.summary["tasks_reached"]) == ["t1", "t2", "t3"], out.summary
    assert not sub.on("errors")
    assert events(sub, "bus_task_change")[0]["add"] == ["t3"]
    assert events(sub, "replan")
    assert any(leg["task"] == "t3" for p in sub.on("plan") for s in p["stops"] for leg in s["rovers"])


@pytest.mark.slow
async def test_broker_killed_mid_mission(tmp_path: Path) -> None:
    broker = Broker(tmp_path)
    broker.start()
    prefix = "test/kill"
    mission = bus_mission(tmp_path, broker.port, prefix)
    try:
        async with Subscriber(broker.port, prefix) as sub:
            task, probe = await _fly_with(mission, tmp_path, "run", dwell=150.0)
            await sub.wait_for(lambda: sub.on("vehicles/r1/telemetry"), "telemetry")
            broker.stop()
            await sub.wait_for(lambda: probe.state is not None and any(
                e.kind == "bus_reconnecting" for e in probe.state.events), "the bus to notice")
            assert not task.done()
            restarted = time.monotonic()
            broker.start()
            await sub.wait_for(lambda: sub.on("vehicles/r1/telemetry", since=restarted), "telemetry again")
            out = await asyncio.wait_for(task, WAIT * 3)
            await sub.wait_for(lambda: any(isinstance(s, dict) and s.get("status") == "done"
                                           for s in sub.on("status", since=restarted)), "final status")
    finally:
        broker.stop()
    assert out.exit_code == 0, out.error
    assert out.summary["result"] == "complete"
    journal = (Path(out.run_dir) / "journal.jsonl").read_text()
    assert '"kind":"bus_reconnecting"' in journal and '"kind":"bus_connected"' in journal
    # events that happened while the broker was away were buffered and sent after it came back
    kinds = [e["kind"] for e in events(sub)]
    assert "bus_reconnecting" in kinds and kinds.count("summary") == 1


async def test_bus_buffer_is_bounded(tmp_path: Path) -> None:
    """With no broker at all the bus keeps at most buffer_size messages and counts the rest."""
    mission = bus_mission(tmp_path, free_tcp_port(), "test/nobroker")
    cfg = bus_config(mission)
    assert cfg is not None
    import dataclasses

    bus = FleetBus(dataclasses.replace(cfg, buffer_size=10), mission)
    bus.start()
    try:
        for i in range(25):
            bus.publish("events", {"i": i})
        assert bus.dropped == 15
        assert "15 dropped" in bus.status_line()
    finally:
        await bus.aclose()


async def _watch_cli(port: int, prefix: str) -> asyncio.subprocess.Process:
    return await asyncio.create_subprocess_exec(
        sys.executable, "-m", "fleetctl.cli", "watch", "--mqtt", f"mqtt://127.0.0.1:{port}",
        "--topic-prefix", prefix, "--headless", "--exit-on-done",
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE, cwd=ROOT)


async def test_watch_renders_the_fleet_from_the_bus(broker: Broker, tmp_path: Path) -> None:
    prefix = "test/watch"
    mission = bus_mission(tmp_path, broker.port, prefix)
    proc = await _watch_cli(broker.port, prefix)
    try:
        line = await asyncio.wait_for(proc.stdout.readline(), WAIT)  # type: ignore[union-attr]
        assert b"watching" in line
        # the watcher subscribes right after printing; give the mission a subscriber to race with
        out = await asyncio.wait_for(execute(mission, "deploy", runs_dir=tmp_path / "runs"), WAIT * 2)
        assert out.exit_code == 0
        stdout, stderr = await asyncio.wait_for(proc.communicate(), WAIT)
    finally:
        if proc.returncode is None:
            proc.kill()
            await proc.wait()
    text = stdout.decode()
    assert proc.returncode == 0, stderr.decode()
    assert "task_reached" in text and "deployment complete" in text
    rows = {w[0]: w for w in map(str.split, text.splitlines())
            if len(w) > 3 and w[0] in ("carrier", "r1", "r2") and w[1] in ("carrier", "rover")}
    assert set(rows) == {"carrier", "r1", "r2"}, text
    assert rows["carrier"][1] == "carrier" and rows["r1"][2] == "on_task" and rows["r2"][2] == "on_task"
    assert "ctltest" in text and "controller done" in text


async def test_watch_python_api(broker: Broker, tmp_path: Path) -> None:
    """The Watcher's state and render_text, from the retained topics of a finished mission."""
    from fleetctl.views.watch import Watcher, render_text

    prefix = "test/watchapi"
    mission = bus_mission(tmp_path, broker.port, prefix)
    out = await asyncio.wait_for(execute(mission, "deploy", runs_dir=tmp_path / "runs"), WAIT * 2)
    assert out.exit_code == 0
    cfg = bus_config(mission)
    assert cfg is not None
    watcher = Watcher(cfg)
    runner = asyncio.create_task(watcher.run())
    try:
        await asyncio.wait_for(watcher.finished.wait(), WAIT)
        while watcher.state.plan is None:  # retained plan and status arrive in either order
            await asyncio.sleep(0.05)
    finally:
        runner.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await runner
    assert watcher.state.remote_status == "done" and watcher.state.phase == "done"
    assert watcher.state.plan["kind"] == "deploy"
    assert "plan: deploy" in render_text(watcher)
