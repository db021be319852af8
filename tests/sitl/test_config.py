"""FleetConfig from a parsed mission-file dict (the structure of docs/mission-file.md), and the CLI."""

from __future__ import annotations

import copy
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from sitl import ConfigError, Fault, FleetConfig, LinkError, SimFleet

MISSION = yaml.safe_load("""
name: recon
origin: {lat: 47.397742, lon: 8.545594, alt: 488.0}
carrier:
  id: carrier
  connection: sim
  sysid: 1
  position: [52, 60]
  heading_deg: 0
  max_speed: 15.0
  accel: 10.0
  turn_rate: 3.0
  unload_time: 4.0
  load_time: 4.0
rovers:
  max_speed: 1.0
  accel: null
  deploy_range: 25.0
  endurance_range: 60.0
  reserve: 0.1
  fleet: {count: 16, sysid_start: 11}
tasks:
  - {id: t1, position: [57, 11, 4]}
  - {id: t2, lat: 47.3981, lon: 8.5461, alt: 495.0}
sim:
  speedup: 1.0
  faults:
    - {vehicle: r3, kind: dropout, at: 20.0, until: 45.0}
    - {kind: packet_loss, rate: 0.2}
    - {kind: latency, seconds: 0.2}
    - {vehicle: r2, kind: battery_drain, factor: 2.0}
    - {vehicle: r5, kind: refuse_arm}
links: {heartbeat_timeout: 3.0}
planner: {deploy: lee, collect: lee, seed: 7}
dwell: 60.0
""")


def test_design_example_mission() -> None:
    cfg = FleetConfig.from_mission_dict(MISSION)
    assert cfg.origin == (47.397742, 8.545594, 488.0)
    assert cfg.carrier.position == (52.0, 60.0, 0.0) and cfg.carrier.turn_rate == 3.0
    assert [r.id for r in cfg.rovers] == [f"r{k}" for k in range(1, 17)]
    assert [r.sysid for r in cfg.rovers] == list(range(11, 27))
    assert all(r.connection is None and r.position is None and r.endurance_range == 60.0 for r in cfg.rovers)
    assert cfg.seed == 7 and cfg.speedup == 1.0
    assert cfg.faults[0] == Fault("dropout", vehicle="r3", at=20.0, until=45.0)
    assert cfg.faults[3] == Fault("battery_drain", vehicle="r2", factor=2.0)
    assert FleetConfig.from_mission_dict(MISSION, speedup=8.0, autopilot="ardupilot").speedup == 8.0


def test_units_with_own_connections_and_positions() -> None:
    d = copy.deepcopy(MISSION)
    d["rovers"].pop("fleet")
    d["rovers"]["units"] = [
        {"id": "a", "sysid": 21, "connection": "udpin://127.0.0.1:14600"},
        {"id": "b", "sysid": 22, "position": [5, 6, 0]},
    ]
    d["sim"] = {"speedup": 3, "seed": 4, "autopilot": "ardupilot"}
    cfg = FleetConfig.from_mission_dict(d)
    a, b = cfg.rovers
    assert a.connection == "udpin://127.0.0.1:14600" and a.position is None
    assert b.connection is None and b.position == (5.0, 6.0, 0.0)
    assert cfg.seed == 4 and cfg.autopilot == "ardupilot" and cfg.speedup == 3.0


@pytest.mark.parametrize(("path", "value", "message"), [
    (("carrier", "max_speed"), -1.0, "carrier.max_speed"),
    (("rovers", "fleet", "count"), "many", "rovers.fleet.count"),
    (("origin",), {"lat": 100, "lon": 0}, "origin"),
    (("sim", "faults"), [{"kind": "packet_loss", "rate": 2.0}], r"sim.faults\[0\]"),
    (("sim", "faults"), [{"kind": "dropout", "vehicle": "r99"}], "r99"),
    (("rovers", "fleet"), {"count": 3, "sysid_start": 1}, "sysid 1 is used twice"),
])
def test_errors_name_the_key(path: tuple[str, ...], value: object, message: str) -> None:
    d = copy.deepcopy(MISSION)
    node = d
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    with pytest.raises(ConfigError, match=message):
        FleetConfig.from_mission_dict(d)


async def test_connections_bind_and_send_as_the_controller_url_says() -> None:
    import asyncio

    loop = asyncio.get_running_loop()
    received: list[bytes] = []

    class Listener(asyncio.DatagramProtocol):
        def datagram_received(self, data: bytes, addr: object) -> None:
            received.append(data)

    transport, _ = await loop.create_datagram_endpoint(Listener, local_addr=("127.0.0.1", 0))
    port = transport.get_extra_info("sockname")[1]
    d = copy.deepcopy(MISSION)
    d["sim"] = {"speedup": 10}
    d["carrier"]["connection"] = "udp://127.0.0.1:0"
    d["rovers"].pop("fleet")
    d["rovers"]["units"] = [{"id": "r1", "sysid": 11, "connection": f"udpin://127.0.0.1:{port}"},
                            {"id": "r2", "sysid": 12}, {"id": "r3", "sysid": 13, "connection": "sim"}]
    try:
        async with SimFleet(FleetConfig.from_mission_dict(d)) as fleet:
            eps = fleet.endpoints
            assert eps["r1"] == f"udpin://127.0.0.1:{port}"
            assert eps["carrier"].startswith("udp://127.0.0.1:") and not eps["carrier"].endswith(":0")
            assert eps["r2"] == eps["carrier"]  # no connection of its own: the carrier's link
            assert eps["r3"] not in (eps["carrier"], eps["r1"])
            await fleet.wait_for(lambda: len(received) >= 3, timeout=3)  # r1 sends to the listener
    finally:
        transport.close()


def test_unservable_connections() -> None:
    d = copy.deepcopy(MISSION)
    d["carrier"]["connection"] = "serial:///dev/ttyACM0?baud=57600"
    with pytest.raises(LinkError, match="serial"):
        SimFleet(FleetConfig.from_mission_dict(d))
    d["carrier"]["connection"] = "udpin://127.0.0.1"
    with pytest.raises(LinkError, match="port"):
        SimFleet(FleetConfig.from_mission_dict(d))


def test_python_m_sitl_prints_endpoints_and_stops_on_sigint(tmp_path: Path) -> None:
    import signal

    d = copy.deepcopy(MISSION)
    d["rovers"]["fleet"]["count"] = 2
    d["sim"] = {"speedup": 5}
    mission = tmp_path / "m.yaml"
    mission.write_text(yaml.safe_dump(d))
    proc = subprocess.Popen([sys.executable, "-m", "sitl", "--mission", str(mission), "--speedup", "2"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        lines = [proc.stdout.readline() for _ in range(5)]  # type: ignore[union-attr]
        assert "speedup 2" in lines[0]
        assert lines[1].split()[0] == "carrier" and "udp://127.0.0.1:" in lines[1]
        assert lines[3].split()[:3] == ["r2", "sysid", "12"]
        assert lines[4].startswith("serving")
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=5)


def test_python_m_sitl_reports_a_bad_mission(tmp_path: Path) -> None:
    d = copy.deepcopy(MISSION)
    d["carrier"]["max_speed"] = "fast"
    mission = tmp_path / "bad.yaml"
    mission.write_text(yaml.safe_dump(d))
    out = subprocess.run([sys.executable, "-m", "sitl", "--mission", str(mission)], capture_output=True,
                         text=True, timeout=30)
    assert out.returncode == 2
    assert "carrier.max_speed" in out.stderr and "Traceback" not in out.stderr


async def test_port_in_use_is_reported() -> None:
    import socket

    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    try:
        d = copy.deepcopy(MISSION)
        d["carrier"]["connection"] = f"udp://127.0.0.1:{sock.getsockname()[1]}"
        fleet = SimFleet(FleetConfig.from_mission_dict(d))
        with pytest.raises(LinkError, match="choose another port"):
            await fleet.start()
        assert not fleet.running
    finally:
        sock.close()


async def test_rovers_placed_in_the_field() -> None:
    d = copy.deepcopy(MISSION)
    d["rovers"].pop("fleet")
    d["rovers"]["units"] = [{"id": "a", "sysid": 21, "position": [57, 11, 8]},
                            {"id": "b", "sysid": 22, "position": [40, 20]}]
    d["sim"] = {"speedup": 10}
    async with SimFleet(FleetConfig.from_mission_dict(d)) as fleet:
        snap = fleet.snapshot()
        a, b = snap["a"], snap["b"]
        assert a["position"] == (57.0, 11.0, 8.0) and a["armed"] and not a["on_ground"]
        assert b["position"] == (40.0, 20.0, 0.0) and b["on_ground"] and not b["loaded"]
        assert snap["carrier"]["position"] == (52.0, 60.0, 0.0)
        t = fleet.sim_time
        await fleet.wait_sim_time(t + 0.5, timeout=3)
        assert fleet.rover("a").position == (57.0, 11.0, 8.0)  # hovers in place
