"""``watch --web``: the web map fed from the MQTT bus alone (a real mosquitto on a free port)."""

from __future__ import annotations

import asyncio
import contextlib
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
from views_helpers import mission_dict, write_mission

from fleetctl.bus.config import BusConfig
from fleetctl.mission import load_mission
from fleetctl.run.runner import execute
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
