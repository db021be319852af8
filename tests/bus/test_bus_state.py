"""The MQTT connection state is shown: ``--headless`` lines of deploy and watch, and the summary's
``"mqtt"`` section (docs/summary-json.md), with no broker on the port and with a real mosquitto."""

from __future__ import annotations

import asyncio
import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from fleetctl.run.flight import execute  # noqa: E402
from tests.bus.test_bus import MOSQUITTO, PASSWORD, WAIT, Broker, _fly_with, bus_mission, free_tcp_port  # noqa: E402
from tests.run.ctl_helpers import mission_dict, write_mission

ROOT = Path(__file__).resolve().parents[2]


def _deploy_cli(tmp_path: Path, mqtt: str) -> subprocess.CompletedProcess[str]:
    path = write_mission(mission_dict(rovers=1), tmp_path / "m.yaml")
    cmd = [sys.executable, "-m", "fleetctl.cli", "deploy", "--mission", str(path), "--headless",
           "--mqtt", mqtt, "--runs", str(tmp_path / "runs"), "--summary", str(tmp_path / "s.json")]
    return subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=120)


@pytest.mark.slow
def test_a_dead_broker_is_not_silent(tmp_path: Path) -> None:
    url = f"mqtt://127.0.0.1:{free_tcp_port()}"  # nothing listens there
    p = _deploy_cli(tmp_path, url)
    assert p.returncode == 0, p.stderr  # the mission flies without its bus
    assert f"bus: cannot connect to {url}" in p.stdout, p.stdout
    mqtt = json.loads((tmp_path / "s.json").read_text())["mqtt"]
    assert mqtt["state"] == "reconnecting" and mqtt["connects"] == 0 and mqtt["disconnects"] == 0
    assert mqtt["last_error"] and mqtt["url"] == url


def test_without_a_bus_the_summary_says_null(tmp_path: Path) -> None:
    mission = write_mission(mission_dict(rovers=1), tmp_path / "m.yaml")
    from fleetctl.mission import load_mission

    out = asyncio.run(execute(load_mission(mission), "deploy", runs_dir=tmp_path / "runs"))
    assert out.exit_code == 0 and out.summary["mqtt"] is None


@pytest.mark.slow
@pytest.mark.skipif(MOSQUITTO is None, reason="mosquitto binary not installed")
def test_a_live_broker(tmp_path: Path) -> None:
    broker = Broker(tmp_path)
    broker.start()
    try:
        p = _deploy_cli(tmp_path, broker.url)
    finally:
        broker.stop()
    assert p.returncode == 0, p.stderr
    assert f"bus: connected to {broker.url}" in p.stdout and "cannot connect" not in p.stdout
    mqtt = json.loads((tmp_path / "s.json").read_text())["mqtt"]
    assert mqtt["state"] == "connected" and mqtt["connects"] == 1 and mqtt["disconnects"] == 0
    assert mqtt["last_error"] is None and mqtt["published"] > 0


@pytest.mark.slow
@pytest.mark.skipif(MOSQUITTO is None, reason="mosquitto binary not installed")
async def test_a_broker_that_dies_counts_a_disconnect(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FLEETCTL_TEST_MQTT_PASSWORD", PASSWORD)
    broker = Broker(tmp_path)
    broker.start()
    mission = bus_mission(tmp_path, broker.port, "test/state", rovers=1)
    task, probe = await _fly_with(mission, tmp_path, "run", dwell=60.0)
    try:
        async with asyncio.timeout(WAIT):
            while probe.state is None or not any(e.kind == "bus_connected" for e in probe.state.events):
                await asyncio.sleep(0.05)
        broker.stop()
        out = await asyncio.wait_for(task, WAIT * 3)
    finally:
        broker.stop()
    mqtt = out.summary["mqtt"]
    assert mqtt["connects"] == 1 and mqtt["disconnects"] == 1 and mqtt["state"] == "reconnecting"
    assert mqtt["last_error"]


def test_watch_headless_says_it_cannot_connect(tmp_path: Path) -> None:
    url = f"mqtt://127.0.0.1:{free_tcp_port()}"
    cmd = [sys.executable, "-m", "fleetctl.cli", "watch", "--mqtt", url, "--topic-prefix", "x/y",
           "--headless"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        assert proc.stdout is not None
        lines = [proc.stdout.readline() for _ in range(2)]
        assert "watching" in lines[0] and f"bus: cannot connect to {url}" in lines[1], lines
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert f"bus: reconnecting {url} x/y (" in out  # the final table's status line keeps the reason
