"""A failed connect is one short line per vehicle: ``r3 (sysid 13): no heartbeat within 10 s on URL``
(real CLI runs in a subprocess; they need --yes since there is no terminal)."""

from __future__ import annotations

import asyncio
import subprocess
import sys
from pathlib import Path

from tests.run.ctl_helpers import free_udp_port, mission_dict, sim_fleet, write_mission

ROOT = Path(__file__).resolve().parents[2]
MAX_LINE = 200


def _deploy(path: Path, tmp_path: Path) -> list[str]:
    return [sys.executable, "-m", "fleetctl.cli", "deploy", "--mission", str(path), "--yes", "--headless",
            "--timeout", "1", "--runs", str(tmp_path / "runs")]


def _assert_short(text: str) -> None:
    long = [line for line in text.splitlines() if len(line) > MAX_LINE]
    assert not long, long


def test_nothing_on_the_port(tmp_path: Path) -> None:
    url = f"udp://127.0.0.1:{free_udp_port()}"  # nobody there
    path = write_mission(mission_dict(rovers=2, carrier_connection=url), tmp_path / "m.yaml")
    p = subprocess.run(_deploy(path, tmp_path), capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert p.returncode == 1, p.stderr
    assert f"carrier (sysid 1): no heartbeat within 1 s on {url}" in p.stderr
    assert "Traceback" not in p.stderr + p.stdout
    _assert_short(p.stdout + p.stderr)


async def test_one_line_per_missing_rover(tmp_path: Path) -> None:
    url = f"udp://127.0.0.1:{free_udp_port()}"
    async with sim_fleet(mission_dict(rovers=1, carrier_connection=url)):  # the carrier and r1 only
        path = write_mission(mission_dict(rovers=2, carrier_connection=url), tmp_path / "m.yaml")
        proc = await asyncio.create_subprocess_exec(
            *_deploy(path, tmp_path), stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
            cwd=ROOT)
        out_b, err_b = await asyncio.wait_for(proc.communicate(), 60)
    out, err = out_b.decode(), err_b.decode()
    assert proc.returncode == 1, err
    assert "only 1 rover(s) answered for 2 tasks" in err
    assert f"\n  r2 (sysid 12): no heartbeat within 1 s on {url}" in err
    assert "r1 (sysid" not in err and "carrier (sysid" not in err
    _assert_short(out + err)
