"""`fleetctl status` and `fleetctl sim` (against the simulated fleet over real UDP)."""

from __future__ import annotations

import asyncio
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fleetctl.cli import main
from tests.run.ctl_helpers import free_udp_port, mission_dict, sim_fleet, write_mission

ROOT = Path(__file__).resolve().parents[2]


def test_status_against_the_embedded_sim(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_mission(mission_dict(rovers=2, speedup=10.0), tmp_path / "m.yaml")
    rc = main(["status", "--mission", str(path), "--timeout", "5"])
    out = capsys.readouterr().out
    assert rc == 0, out
    for vid in ("carrier", "r1", "r2"):
        assert re.search(rf"^{vid}\t(carrier|rover)\t", out, re.M), out  # plain lines without a terminal
    assert out.count("on deck") == 2 and out.count("ready") >= 3
    assert "px4" in out and "disarmed" in out and "100 %" in out
    assert "all 3 vehicles connected and ready" in out


def test_status_names_a_vehicle_that_does_not_answer(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    url = f"udp://127.0.0.1:{free_udp_port()}"  # nobody there
    path = write_mission(mission_dict(rovers=1, carrier_connection=url), tmp_path / "m.yaml")
    rc = main(["status", "--mission", str(path), "--timeout", "1.2"])
    cap = capsys.readouterr()
    assert rc == 1
    assert f"carrier (sysid 1): no heartbeat within 1.2 s on {url}" in cap.err
    assert f"r1 (sysid 11): no heartbeat within 1.2 s on {url}" in cap.err
    assert "no answer" in cap.out


async def test_status_against_an_external_fleet_with_a_missing_rover(tmp_path: Path) -> None:
    url = f"udp://127.0.0.1:{free_udp_port()}"
    async with sim_fleet(mission_dict(rovers=2, carrier_connection=url)):
        path = write_mission(mission_dict(rovers=3, carrier_connection=url), tmp_path / "m.yaml")
        proc = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "fleetctl.cli", "status", "--mission", str(path), "--timeout", "2",
            stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE, cwd=ROOT)
        out, err = await asyncio.wait_for(proc.communicate(), 30)
    assert proc.returncode == 1, err.decode()
    assert f"r3 (sysid 13): no heartbeat within 2 s on {url}" in err.decode()
    assert "carrier (sysid 1)" not in err.decode() and "r1 (sysid" not in err.decode()
    assert out.decode().count("on deck") == 2


def test_sim_serves_and_prints_endpoints(tmp_path: Path) -> None:
    path = write_mission(mission_dict(rovers=2), tmp_path / "m.yaml")
    cmd = [sys.executable, "-m", "fleetctl.cli", "sim", "--mission", str(path), "--speedup", "3"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        lines = []
        deadline = time.monotonic() + 20
        assert proc.stdout is not None
        while len([ln for ln in lines if "udp://" in ln]) < 3 and time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line)
        text = "".join(lines)
        assert "running at 3x" in text, text
        rows = re.finditer(r"^\s+(\S+)\s+sysid \d+\s+(udp://\S+)$", text, re.M)
        urls = {m.group(1): m.group(2) for m in rows}
        assert set(urls) == {"carrier", "r1", "r2"} and len(set(urls.values())) == 1
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, err
    assert "stopped" in out


def test_sim_rejects_a_link_it_cannot_simulate(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_mission(mission_dict(carrier_connection="tcp://127.0.0.1:5760"), tmp_path / "m.yaml")
    rc = main(["sim", "--mission", str(path)])
    err = capsys.readouterr().err
    assert rc == 2 and "tcp://127.0.0.1:5760" in err and "UDP only" in err
