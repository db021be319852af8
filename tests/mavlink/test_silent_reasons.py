"""A vehicle that does not answer is reported with what its link heard instead: nothing at all,
other system ids, or its messages refused by signing (unsigned, another key)."""

from __future__ import annotations

import asyncio
import socket
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.mavlink.fleet import connect_fleet
from tests.run.ctl_helpers import free_udp_port, mission_dict, mission_from

KEY = "11" * 32


def _heartbeats(port: int, sysid: int, *, key: bytes | None = None,
                seconds: float = 1.5) -> asyncio.Task[None]:
    """Send a vehicle's HEARTBEAT (unsigned, or signed with ``key``) to 127.0.0.1:port at 10 Hz."""
    mav = M.MAVLink(None, srcSystem=sysid, srcComponent=1)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.link_id = 0
        mav.signing.timestamp = 1

    async def run() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for _ in range(int(seconds * 10)):
                hb = mav.heartbeat_encode(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_PX4, 0, 0,
                                          M.MAV_STATE_STANDBY)
                s.sendto(hb.pack(mav), ("127.0.0.1", port))
                await asyncio.sleep(0.1)

    return asyncio.create_task(run())


async def _connect(tmp_path: Path, port: int, **links: object) -> list[str]:
    d = mission_dict(rovers=1, carrier_connection=f"udpin://127.0.0.1:{port}")
    d["links"].update(links)
    fleet = await connect_fleet(mission_from(d, tmp_path), timeout=1.0, require_all=False,
                                configure_streams=False)
    try:
        return [fleet.failure_line(vid) for vid in fleet.missing()]
    finally:
        await fleet.close()


async def test_no_traffic_at_all_is_said(tmp_path: Path) -> None:
    lines = await _connect(tmp_path, free_udp_port())
    assert lines and all("no MAVLink traffic at all on this link" in line for line in lines)


async def test_another_system_id_is_named(tmp_path: Path) -> None:
    port = free_udp_port()
    sender = _heartbeats(port, 42)
    lines = await _connect(tmp_path, port)
    await sender
    carrier = [line for line in lines if line.startswith("carrier (sysid 1)")]
    assert carrier and "heard system id(s) 42" in carrier[0], lines


async def test_unsigned_heartbeats_on_a_signed_link_are_said(tmp_path: Path,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FLEET_KEY", KEY)
    port = free_udp_port()
    sender = _heartbeats(port, 1)  # the carrier, unsigned: not yet provisioned
    lines = await _connect(tmp_path, port, signing={"key_env": "FLEET_KEY"})
    await sender
    carrier = next(line for line in lines if line.startswith("carrier"))
    assert "heard, but unsigned" in carrier and "fleetctl keys provision" in carrier
    other = _heartbeats(port, 1, key=bytes.fromhex("22" * 32))  # signed with another key
    lines = await _connect(tmp_path, port, signing={"key_env": "FLEET_KEY"})
    await other
    assert any("signed with another key" in line for line in lines if line.startswith("carrier")), lines
