"""Field safety: MAVLink 2 signing between fleetctl's links and the simulated fleet over
real UDP, spoofed and replayed packets from another local socket, provisioning with SETUP_SIGNING,
a resumed controller's persisted timestamp, and route takeover without signing."""

from __future__ import annotations

import asyncio
import base64
import secrets
import socket
from collections.abc import AsyncIterator, Iterator
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.mavlink.fleet import Fleet, connect_fleet
from fleetctl.mavlink.link import Link, LinkError, LinkTimeout
from fleetctl.mavlink.signing import LEASE, SigningKey, SigningKeyError, now_timestamp
from fleetctl.mission import MissionError
from sitl import SimFleet
from tests.run.ctl_helpers import mission_dict, mission_from, sim_fleet

KEY_HEX = secrets.token_hex(32)
KEY = SigningKey(bytes.fromhex(KEY_HEX))
ENV = "FLEETCTL_TEST_SIGNING_KEY"


def signed_dict(**kw: Any) -> dict[str, Any]:
    d = mission_dict(**kw)
    d["links"]["signing"] = {"key_env": ENV}
    return d


@pytest.fixture
def key_env(monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    monkeypatch.setenv(ENV, KEY_HEX)
    yield ENV


@pytest.fixture
async def signed(key_env: str, tmp_path: Path) -> AsyncIterator[tuple[SimFleet, Fleet]]:
    d = signed_dict()
    async with sim_fleet(d) as sim:
        assert sim.config.signing_key == KEY.secret  # provisioned from links.signing.key_env
        async with await connect_fleet(mission_from(d, tmp_path), sim.endpoints, timeout=5.0,
                                       signing_state=tmp_path) as fleet:
            yield sim, fleet


class Spoofer:
    """Another local socket that sends crafted MAVLink to the controller's link."""

    def __init__(self, port: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.dest = ("127.0.0.1", port)

    def send(self, data: bytes) -> None:
        self.sock.sendto(data, self.dest)

    def close(self) -> None:
        self.sock.close()


def codec(sysid: int, key: bytes | None = None, timestamp: int | None = None) -> Any:
    mav = M.MAVLink(None, srcSystem=sysid, srcComponent=1)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.timestamp = timestamp if timestamp is not None else now_timestamp() + 1000
    return mav


def armed_heartbeat(mav: Any) -> bytes:
    return bytes(mav.heartbeat_encode(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_PX4,
                                      M.MAV_MODE_FLAG_SAFETY_ARMED | M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                                      0, M.MAV_STATE_ACTIVE).pack(mav))


def far_position(mav: Any, lat: float = 47.40, lon: float = 8.55) -> bytes:
    return bytes(mav.global_position_int_encode(1000, int(lat * 1e7), int(lon * 1e7), 600000, 100000,
                                                0, 0, 0, 0).pack(mav))


# ------------------------------------------------------------------------------------ keys, mission


def test_key_parsing_never_shows_the_key(monkeypatch: pytest.MonkeyPatch) -> None:
    raw = bytes.fromhex(KEY_HEX)
    assert SigningKey.parse(KEY_HEX) == KEY
    assert SigningKey.parse(base64.b64encode(raw).decode()) == KEY
    assert SigningKey.parse(base64.urlsafe_b64encode(raw).decode().rstrip("=")) == KEY
    for text in (repr(KEY), str(KEY), f"{KEY}", repr([KEY])):
        assert KEY_HEX not in text and "hidden" in text
    with pytest.raises(SigningKeyError, match="32 bytes") as exc:
        SigningKey.parse(KEY_HEX[:-2], "environment variable X")
    assert KEY_HEX[:-2] not in str(exc.value) and "environment variable X" in str(exc.value)
    monkeypatch.delenv("NOPE_KEY", raising=False)
    with pytest.raises(SigningKeyError, match="NOPE_KEY .*is not set"):
        SigningKey.from_env("NOPE_KEY")


def test_mission_signing_section(tmp_path: Path) -> None:
    m = mission_from(signed_dict(), tmp_path)
    assert m.links.signing is not None and m.links.signing.key_env == ENV
    assert mission_from(mission_dict(), tmp_path).links.signing is None
    for bad, msg in (({"key_env": "1X"}, "not an environment variable name"),
                     ({"key_env": ENV, "key": "abc"}, "unknown key"), ({}, "required key")):
        d = mission_dict()
        d["links"]["signing"] = bad
        with pytest.raises(MissionError, match=msg):
            mission_from(d, tmp_path)


async def test_connect_names_an_unset_or_malformed_key(monkeypatch: pytest.MonkeyPatch,
                                                       tmp_path: Path) -> None:
    mission = mission_from(signed_dict(), tmp_path)
    monkeypatch.delenv(ENV, raising=False)
    with pytest.raises(LinkError, match=f"{ENV} .*not set"):
        await connect_fleet(mission, {"carrier": "udp://127.0.0.1:9", "r1": "udp://127.0.0.1:9",
                                      "r2": "udp://127.0.0.1:9"}, timeout=0.5)
    monkeypatch.setenv(ENV, "deadbeef")
    with pytest.raises(LinkError, match=f"{ENV}.*32 bytes") as exc:
        await connect_fleet(mission, {"carrier": "udp://127.0.0.1:9"}, timeout=0.5)
    assert "deadbeef" not in str(exc.value)


# ------------------------------------------------------------------------------------ signed fleet


async def test_signed_fleet_flies_and_the_sim_checks_signatures(signed: tuple[SimFleet, Fleet]) -> None:
    sim, fleet = signed
    assert fleet.signing
    r1 = fleet.rovers["r1"]
    await r1.wait_until(lambda v: v.position is not None and v.battery_pct is not None, 3.0, "telemetry")
    await r1.arm()
    assert sim.vehicle("r1").armed
    assert sum(fleet.link_rejections().values()) == 0
    assert sim.signing_rejections() == {"unsigned": 0, "bad_signature": 0, "replay": 0}
    # an unsigned ground station and one with a wrong key are not obeyed by a signed vehicle
    for key in (None, SigningKey(secrets.token_bytes(32))):
        async with Link(sim.endpoints["carrier"], sysid=254, signing_key=key, signing_state=False) as other:
            with pytest.raises(LinkTimeout):
                await other.command(12, M.MAV_CMD_COMPONENT_ARM_DISARM, (1,), timeout=0.2, retries=1)
            if key is not None:  # and it rejects the vehicles' telemetry, signed with the fleet key
                assert other.rejected["rejected_bad_signature"] > 0
    assert not sim.vehicle("r2").armed
    rej = sim.signing_rejections("r2")
    assert rej["unsigned"] >= 2 and rej["bad_signature"] >= 2


async def test_spoofed_unsigned_messages_change_nothing(signed: tuple[SimFleet, Fleet]) -> None:
    sim, fleet = signed
    link = fleet.links[fleet.urls["r1"]]
    r1, carrier = fleet.rovers["r1"], fleet.carrier
    await r1.wait_until(lambda v: v.position is not None, 3.0, "position")
    route = dict(link.routes)
    spoof = Spoofer(link.local_port or 0)
    try:
        r1_mav, carrier_mav = codec(11), codec(1)
        for _ in range(5):
            spoof.send(armed_heartbeat(carrier_mav))
            spoof.send(far_position(r1_mav))
        sim.dropout("r1")  # r1 falls silent: no real ACK will come
        task = asyncio.ensure_future(link.command(11, M.MAV_CMD_COMPONENT_ARM_DISARM, (1,), timeout=0.3,
                                                  retries=2))
        for _ in range(10):
            spoof.send(bytes(r1_mav.command_ack_encode(M.MAV_CMD_COMPONENT_ARM_DISARM, M.MAV_RESULT_ACCEPTED,
                                                       0, 0, 255, 190).pack(r1_mav)))
            await asyncio.sleep(0.1)
        with pytest.raises(LinkTimeout):
            await task
    finally:
        spoof.close()
    assert link.routes == route
    assert not carrier.armed and not sim.vehicle("carrier").armed
    assert r1.enu is not None and max(abs(c) for c in r1.enu[:2]) < 5.0  # still where the sim has it
    rej = fleet.link_rejections()
    assert rej["rejected_unsigned"] >= 20 and rej["rejected_bad_signature"] == 0


async def test_replayed_and_wrongly_signed_packets_are_rejected(signed: tuple[SimFleet, Fleet]) -> None:
    sim, fleet = signed
    link = fleet.links[fleet.urls["r1"]]
    captured: list[bytes] = []
    parser = M.MAVLink(None)

    def tap(direction: str, ts: float, data: bytes) -> None:
        if direction == "in":
            for m in parser.parse_buffer(data) or []:
                if m.get_type() == "HEARTBEAT" and m.get_srcSystem() == 1:
                    captured.append(bytes(m.get_msgbuf()))

    remove = link.add_tap(tap)
    await fleet.carrier.wait_until(lambda v: len(captured) >= 1, 3.0, "a heartbeat")
    remove()
    assert captured[0][2] & 0x01  # signed
    spoof = Spoofer(link.local_port or 0)
    try:
        for _ in range(3):
            spoof.send(captured[0])  # an authentic packet, sent again
        wrong = codec(1, secrets.token_bytes(32))
        for _ in range(3):
            spoof.send(armed_heartbeat(wrong))
        old = codec(1, KEY.secret, timestamp=now_timestamp() - 120 * 100_000)  # right key, 2 min old
        spoof.send(armed_heartbeat(old))
        await asyncio.sleep(0.3)
    finally:
        spoof.close()
    assert link.rejected["rejected_replay"] == 4
    assert link.rejected["rejected_bad_signature"] == 3
    assert not fleet.carrier.armed
    assert link.route_conflicts == 0  # refused before routing


# ------------------------------------------------------------------------------------ resume


async def test_resumed_link_continues_above_the_persisted_timestamp(key_env: str, tmp_path: Path) -> None:
    d = signed_dict(rovers=1)
    state = tmp_path / "state.json"
    async with sim_fleet(d) as sim:
        url = sim.endpoints["r1"]
        first = Link(url, signing_key=KEY, signing_state=state)
        async with first:
            await first.expect("HEARTBEAT", sysid=11)
            for _ in range(3):
                assert (await first.command(11, M.MAV_CMD_REQUEST_MESSAGE, (M.MAVLINK_MSG_ID_HOME_POSITION,))
                        ).accepted
            assert first.signer is not None
            last = first.signer.timestamp
        assert state.exists() and KEY_HEX not in state.read_text()
        # a controller whose clock is behind what it sent before (e.g. pulled ahead by a vehicle's
        # clock, then restarted): without the state it is rejected as a replay
        lagging = Link(url, signing_key=KEY, signing_state=False)
        assert lagging.signer is not None and lagging._verifier is not None
        lagging.signer.stamp = lambda: None  # type: ignore[method-assign]  # freeze it in the past
        lagging._verifier._seen = None
        lagging.mav.signing.timestamp = last - 1000
        async with lagging:
            with pytest.raises(LinkTimeout):
                await lagging.command(11, M.MAV_CMD_REQUEST_MESSAGE, (M.MAVLINK_MSG_ID_HOME_POSITION,),
                                      timeout=0.2, retries=1)
        assert sim.signing_rejections("r1")["replay"] >= 2
        # the resumed controller starts above everything the first one sent, and is obeyed
        resumed = Link(url, signing_key=KEY, signing_state=state)
        assert resumed.signer is not None and resumed.signer.start > last
        async with resumed:
            await resumed.expect("HEARTBEAT", sysid=11)
            assert (await resumed.command(11, M.MAV_CMD_REQUEST_MESSAGE, (M.MAVLINK_MSG_ID_HOME_POSITION,))
                    ).accepted
        # the reservation: what is on disk is always above the next timestamp to be used
        assert resumed.signer.store is not None and resumed.signer.store.load() >= resumed.signer.timestamp
        assert resumed.signer.reserved - resumed.signer.timestamp <= LEASE + 100_000


# ------------------------------------------------------------------------------------ provisioning


async def test_setup_signing_provisions_and_is_refused_while_armed(tmp_path: Path) -> None:
    d = mission_dict(rovers=2)
    async with sim_fleet(d) as sim:
        async with Link(sim.endpoints["carrier"], signing_state=False) as link:
            await link.expect("HEARTBEAT", sysid=12)
            assert (await link.command(12, M.MAV_CMD_COMPONENT_ARM_DISARM, (1,))).accepted
            refused = link.expect("STATUSTEXT", sysid=12, match=lambda m: "refused" in m.text)
            for sysid in (11, 12):
                link.send(link.mav.setup_signing_encode(sysid, 1, list(KEY.secret), now_timestamp()), sysid)
            await asyncio.wait_for(refused, 2.0)
            await sim.wait_for(lambda: sim.vehicle("r1").signing.active, 2.0)
            assert not sim.vehicle("r2").signing.active and sim.vehicle("r1").signing.key == KEY.secret
            # r1 now obeys only signed traffic
            with pytest.raises(LinkTimeout):
                await link.command(11, M.MAV_CMD_REQUEST_MESSAGE, (M.MAVLINK_MSG_ID_HOME_POSITION,),
                                   timeout=0.2, retries=1)
            link.enable_signing(KEY, state=False)
            assert (await link.command(11, M.MAV_CMD_REQUEST_MESSAGE, (M.MAVLINK_MSG_ID_HOME_POSITION,))
                    ).accepted
            # an all-zero key turns signing off again
            link.send(link.mav.setup_signing_encode(11, 1, [0] * 32, 0), 11)
            await sim.wait_for(lambda: not sim.vehicle("r1").signing.active, 2.0)
            link.disable_signing()
            assert (await link.command(11, M.MAV_CMD_REQUEST_MESSAGE, (M.MAVLINK_MSG_ID_HOME_POSITION,))
                    ).accepted


# ------------------------------------------------------------------------------------ without signing


async def test_route_takeover_is_refused_and_reported(fleet: Fleet, sim: SimFleet) -> None:
    link = fleet.links[fleet.urls["r1"]]
    seen: list[tuple[str | None, int]] = []
    fleet.on_route_conflict(lambda vid, sysid, old, new: seen.append((vid, sysid)))
    r1 = fleet.rovers["r1"]
    await r1.wait_until(lambda v: v.position is not None, 3.0, "position")
    route = link.routes[11]
    spoof = Spoofer(link.local_port or 0)
    try:
        mav = codec(11)
        for _ in range(3):
            spoof.send(armed_heartbeat(mav))
            spoof.send(far_position(mav))
        await asyncio.sleep(0.3)
    finally:
        spoof.close()
    assert link.routes[11] == route
    assert not r1.armed and max(abs(c) for c in r1.enu[:2]) < 5.0
    assert link.route_conflicts == 6 and fleet.link_rejections()["route_conflicts"] == 6
    assert seen[0] == ("r1", 11) and len(seen) == 6
    await r1.arm()  # commands still go to the real vehicle
    assert sim.vehicle("r1").armed


@pytest.mark.slow
async def test_provision_sets_keys_and_refuses_an_armed_vehicle(key_env: str, tmp_path: Path) -> None:
    from fleetctl.mavlink.fleet import fleet_urls
    from fleetctl.mavlink.provision import provision

    d = mission_dict(rovers=2)
    mission = mission_from(signed_dict(rovers=2), tmp_path)
    async with sim_fleet(d) as sim:  # the simulated vehicles start without a key
        async with Link(sim.endpoints["carrier"], signing_state=False) as link:
            await link.expect("HEARTBEAT", sysid=12)
            assert (await link.command(12, M.MAV_CMD_COMPONENT_ARM_DISARM, (1,))).accepted
        await sim.wait_for(lambda: sim.vehicle("r2").armed, 2.0)
        results = await provision(mission, KEY, fleet_urls(mission, sim.endpoints), timeout=3.0,
                                  signing_state=tmp_path)
        by_id = {r.vehicle: r for r in results}
        assert by_id["carrier"].ok and by_id["r1"].ok, results
        assert not by_id["r2"].ok and "armed" in by_id["r2"].detail and "r2" in by_id["r2"].line()
        assert sim.vehicle("r1").signing.key == KEY.secret and not sim.vehicle("r2").signing.active
        # provisioning again (the vehicles already have the key) works signed
        sim.vehicle("r2").disarm()
        again = await provision(mission, KEY, fleet_urls(mission, sim.endpoints), timeout=3.0,
                                signing_state=tmp_path)
        assert all(r.ok for r in again), again
        assert sim.vehicle("r2").signing.key == KEY.secret
        # and the mission now connects signed
        async with await connect_fleet(mission, sim.endpoints, timeout=5.0, signing_state=tmp_path) as fleet:
            await fleet.rovers["r2"].arm()
            assert fleet.link_rejections()["rejected_unsigned"] == 0


def test_cli_keys_provision(key_env: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                            capsys: pytest.CaptureFixture[str]) -> None:
    from fleetctl.cli import main
    from tests.run.ctl_helpers import write_mission

    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    path = write_mission(signed_dict(rovers=2), tmp_path / "signed.yaml")
    assert main(["keys", "provision", "--mission", str(path), "--timeout", "3"]) == 0
    out = capsys.readouterr().out
    assert out.count("ok ") == 3 and "r2" in out and KEY_HEX not in out
    assert list((tmp_path / "state" / "fleetctl").glob("signing-*.json"))
    monkeypatch.delenv(ENV)
    assert main(["keys", "provision", "--mission", str(path)]) == 2
    assert f"{ENV}" in capsys.readouterr().err
    plain = write_mission(mission_dict(), tmp_path / "plain.yaml")
    assert main(["keys", "provision", "--mission", str(plain)]) == 2
    assert "links.signing" in capsys.readouterr().err


def test_cli_keys_provision_of_two_teams(key_env: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    """Every vehicle of every team: both carriers (sysids 1 and 2) and their 16 rovers."""
    import yaml

    from fleetctl.cli import main

    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    two = yaml.safe_load((Path(__file__).parents[2] / "missions" / "two_carriers.yaml").read_text())
    two.setdefault("links", {})["signing"] = {"key_env": ENV}
    path = tmp_path / "two.yaml"
    path.write_text(yaml.safe_dump(two))
    assert main(["keys", "provision", "--mission", str(path), "--timeout", "5"]) == 0
    lines = capsys.readouterr().out.splitlines()
    ok = {line.split()[1] for line in lines if line.startswith("ok ")}
    assert ok == {"c1", "c2", *(f"r{i}" for i in range(1, 17))}, lines
    assert lines[-1].startswith("all 18 vehicles sign with key")


# ------------------------------------------------------------------------------------ plausibility


def _gpi(mav: Any, boot_ms: int, lat: float, lon: float) -> bytes:
    return bytes(mav.global_position_int_encode(boot_ms, int(round(lat * 1e7)), int(round(lon * 1e7)),
                                                500000, 12000, 0, 0, 0, 0).pack(mav))


async def test_a_position_jump_is_not_applied_from_one_message() -> None:
    from fleetctl.mavlink.vehicle import Vehicle

    link = Link("udp://127.0.0.1:9")  # never opened: datagrams are fed in as if from the vehicle
    v = Vehicle(link, 11, name="r1", max_speed=5.0)
    mav, addr = codec(11), ("127.0.0.1", 5555)
    lat0, lon0 = 47.397742, 8.545594
    dlat = 1 / 111_319.49  # one metre north
    boot = 10_000
    for k in range(12):  # a track at 2 m/s north, 10 Hz
        link._received(_gpi(mav, boot + 100 * k, lat0 + 0.2 * k * dlat, lon0), addr)
        await asyncio.sleep(0.1)
    assert v.lat == pytest.approx(lat0 + 2.2 * dlat, abs=2e-7)
    # one forged fix 15 m away, even with a stretched clock, is held back
    link._received(_gpi(mav, boot + 100_000, lat0 + 17 * dlat, lon0), addr)
    assert v.lat == pytest.approx(lat0 + 2.2 * dlat, abs=2e-7) and v.positions_held == 1
    # the next fix on the track is applied and discards the held one
    link._received(_gpi(mav, boot + 1200, lat0 + 2.4 * dlat, lon0), addr)
    assert v.lat == pytest.approx(lat0 + 2.4 * dlat, abs=2e-7)
    # forged fixes interleaved with the real stream never get through
    for k in range(6):
        link._received(_gpi(mav, boot + 1300 + 100 * k, lat0 + 40 * dlat, lon0), addr)
        link._received(_gpi(mav, boot + 1300 + 100 * k, lat0 + (2.6 + 0.2 * k) * dlat, lon0), addr)
        await asyncio.sleep(0.05)
    assert abs(v.lat - lat0) < 5 * dlat and v.positions_held == 7
    # a real jump (e.g. a GPS reset) is adopted once consecutive fixes confirm it over 0.2 s
    b = boot + 2000
    for k in range(4):
        link._received(_gpi(mav, b + 150 * k, lat0 + (60 + 0.3 * k) * dlat, lon0), addr)
        if k == 1:
            assert abs(v.lat - lat0) < 5 * dlat  # two agreeing fixes are not enough
        await asyncio.sleep(0.15)
    assert v.lat == pytest.approx(lat0 + 60.9 * dlat, abs=2e-7) and v.positions_held == 9
    v.close()


async def test_item_reached_far_from_the_item_is_ignored(fleet: Fleet, sim: SimFleet) -> None:
    from fleetctl.mavlink.link import MissionItem

    carrier = fleet.carrier
    await carrier.wait_until(lambda v: v.position is not None, 3.0, "position")
    lat, lon, _ = carrier.position
    far = MissionItem(M.MAV_CMD_NAV_WAYPOINT, x=int(round((lat + 60 / 111_319.49) * 1e7)),
                      y=int(round(lon * 1e7)), z=0.0)
    near = MissionItem(M.MAV_CMD_NAV_WAYPOINT, x=int(round(lat * 1e7)), y=int(round(lon * 1e7)), z=0.0)
    await carrier.upload_mission([near, far, far])
    assert len(carrier.mission_items) == 3
    link = carrier.link
    mav = codec(1)
    for seq in (1, 2, 0):  # from the vehicle's own address (as if the vehicle itself said so)
        link._received(bytes(mav.mission_item_reached_encode(seq).pack(mav)), link.routes[1])
    assert carrier.items_reached == {0} and carrier.item_reached_rejected == 2
    assert fleet.link_rejections()["item_reached_rejected"] == 2
