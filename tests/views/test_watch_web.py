"""``watch --web``: the web map fed from the MQTT bus alone (a real mosquitto on a free port)."""

from __future__ import annotations

import asyncio
import contextlib
import copy
import io
import json
import math
import shutil
import socket
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from views_helpers import TWO_TEAMS, mission_dict, write_mission

from fleetctl.bus.config import BusConfig
from fleetctl.mission import load_mission
from fleetctl.run.flight import execute
from fleetctl.views.watch import watch
from fleetctl.views.web import WebMapView

MOSQUITTO = shutil.which("mosquitto") or next(
    (p for p in ("/usr/sbin/mosquitto", "/usr/local/sbin/mosquitto") if Path(p).exists()), None)
WAIT = 60.0  # s: bound on each wait (not a measurement)

pytestmark = pytest.mark.skipif(MOSQUITTO is None, reason="mosquitto is not installed (scripts/test.sh "
                                "installs Debian's mosquitto)")


@pytest.fixture
def broker_port(tmp_path: Path) -> Iterator[int]:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = int(s.getsockname()[1])
    conf = tmp_path / "mosquitto.conf"
    conf.write_text(f"listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n", encoding="utf-8")
    assert MOSQUITTO is not None
    proc = subprocess.Popen([MOSQUITTO, "-c", str(conf)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), 0.2):
                break
            time.sleep(0.05)
        yield port
    finally:
        proc.kill()
        proc.wait(10.0)


@pytest.mark.slow
async def test_watch_web_draws_the_mission_flown_elsewhere(tmp_path: Path, broker_port: int) -> None:
    prefix = "test/watchweb"
    d = mission_dict(rovers=2, speedup=10.0)
    d["mqtt"] = {"url": f"mqtt://127.0.0.1:{broker_port}", "topic_prefix": prefix}
    mission = load_mission(write_mission(d, tmp_path / "mission.yaml"))
    urls: list[str] = []
    web = WebMapView("127.0.0.1", 0, on_ready=urls.append)
    config = BusConfig("127.0.0.1", broker_port, prefix)
    watcher = asyncio.create_task(watch(config, headless=True, exit_on_done=True, out=io.StringIO(),
                                        extra_view=web))
    await asyncio.wait_for(web.ready.wait(), WAIT)
    await asyncio.sleep(0.5)  # the watcher subscribes
    out = await asyncio.wait_for(execute(mission, "deploy", runs_dir=tmp_path / "runs"), WAIT * 2)
    assert out.exit_code == 0
    await asyncio.wait_for(watcher, WAIT)  # the controller's status went 'done'
    hello = json.loads(json.dumps(web.hello()))  # what a page opened now would get (as JSON)
    assert {t["id"] for t in hello["plan"]["tasks"]} == {"t1", "t2"}  # from the plan on the bus
    rovers = {v["id"]: v for v in hello["frame"]["vehicles"] if v["role"] == "rover"}
    assert set(rovers) == {"r1", "r2"}
    tasks = {t["id"]: t["position"] for t in d["tasks"]}
    for v in rovers.values():
        assert v["state"] == "on_task"
        e, n = tasks[v["task"]][:2]
        assert math.hypot(v["e"] - e, v["n"] - n) < 2.0
    assert hello["trails"]["r1"]  # the positions it flew through, from the telemetry topic
    assert urls and urls[0].startswith("http://127.0.0.1:")


async def test_watch_shows_every_team_of_a_run_of_several(tmp_path: Path, broker_port: int) -> None:
    """A two-team deployment in one controller publishes each team under P/teams/<team>: watch
    (its terminal view and its map) shows both teams."""
    from fleetctl.views.watch import Watcher, render_text

    prefix = "test/watchteams"
    d = copy.deepcopy(TWO_TEAMS)
    d["sim"]["speedup"] = 10.0
    d["mqtt"] = {"url": f"mqtt://127.0.0.1:{broker_port}", "topic_prefix": prefix}
    mission = load_mission(write_mission(d, tmp_path / "mission.yaml"))
    web = WebMapView("127.0.0.1", 0)
    out = io.StringIO()
    watcher = Watcher(BusConfig("127.0.0.1", broker_port, prefix))
    watching = asyncio.create_task(watch(watcher.config, headless=True, out=out, extra_view=web,
                                         watcher=watcher))
    await asyncio.wait_for(web.ready.wait(), WAIT)
    async with asyncio.timeout(WAIT):  # subscribed before the run starts: its events are seen
        while watcher.status != "connected":
            await asyncio.sleep(0.05)
    flown = await asyncio.wait_for(execute(mission, "deploy", runs_dir=tmp_path / "runs"), WAIT * 2)
    assert flown.exit_code == 0

    def settled() -> bool:  # the teams' last messages come on their own connections, in any order
        teams = watcher.teams.values()
        rovers = [v for t in teams for v in t.vehicles.values() if v.role == "rover"]
        done = len(teams) == 2 and all(t.remote_status == "done" for t in teams)
        on_task = len(rovers) == 4 and all(v.state == "on_task" for v in rovers)
        return watcher.finished.is_set() and done and on_task

    async with asyncio.timeout(WAIT):
        while not settled():
            await asyncio.sleep(0.05)
    watching.cancel()
    with contextlib.suppress(asyncio.CancelledError):
        await watching
    assert sorted(watcher.teams) == ["c1", "c2"]
    assert watcher.shown.order == web.teams.order == ["c1", "c2"]  # as the run's status names them
    hello = json.loads(json.dumps(web.hello()))
    layers = {x["team"]: x for x in hello["plan"]["teams"]}
    assert sorted(layers) == ["c1", "c2"] and layers["c1"]["colour"] != layers["c2"]["colour"]
    assert all(x["kind"] == "deploy" and len(x["route"]) > 1 for x in layers.values())
    vehicles = {v["id"]: v["team"] for v in hello["frame"]["vehicles"]}
    assert vehicles == {"c1": "c1", "r1": "c1", "r2": "c1", "c2": "c2", "r3": "c2", "r4": "c2"}
    assert {v["state"] for v in hello["frame"]["vehicles"] if v["role"] == "rover"} == {"on_task"}
    text = out.getvalue()
    assert "c1 task_reached" in text and "c2 task_reached" in text  # headless: each team's events, prefixed
    table = render_text(watcher)
    assert "teams: c1 done, c2 done" in table
    heads = [ln.split()[1] for ln in table.splitlines() if ln.startswith("■ ")]
    assert heads == ["c1", "c2"]


def test_the_watcher_bounds_what_the_bus_says() -> None:
    """Team ids, the number of teams and vehicles, and the size of a message are bounded."""
    from fleetctl.views.teams import MAX_TEAMS
    from fleetctl.views.watch import MAX_PAYLOAD, MAX_VEHICLES, Watcher

    w = Watcher(BusConfig("127.0.0.1", 1, "P"))
    new: list[str] = []
    w.on_team = lambda team, st: new.append(team)
    w.handle("P/status", json.dumps({"status": "online", "teams": ["c2", "c1", "bad id", 7]}).encode())
    assert w.shown.order == ["c2", "c1"] and not w.teams
    w.handle("P/teams/c1/status", b'{"status": "online", "phase": "deploy"}')
    w.handle("P/teams/c1/vehicles/r1/telemetry", b'{"role": "rover", "enu": [1, 2, 3]}')
    assert new == ["c1"] and w.teams["c1"].vehicles["r1"].enu == (1, 2, 3)
    for bad in ("P/teams/a b/status", "P/teams/" + "x" * 65 + "/status", "P/teams//status"):
        w.handle(bad, b'{"status": "online"}')
    assert list(w.teams) == ["c1"] and w.ignored == 3
    for k in range(MAX_TEAMS + 5):
        w.handle(f"P/teams/t{k}/status", b'{"status": "online"}')
    assert len(w.teams) == MAX_TEAMS
    for k in range(MAX_VEHICLES + 3):
        w.handle(f"P/teams/c1/vehicles/v{k}/telemetry", b'{"role": "rover"}')
    assert len(w.teams["c1"].vehicles) == MAX_VEHICLES
    w.handle("P/plan", b"[" * (MAX_PAYLOAD + 1))
    assert w.state.plan is None
    w.handle("P/events", b"[" * 100_000)  # too deep for json: text, not an event
    w.handle("P/status", b'{"status": "done"}')
    assert w.finished.is_set()
