"""MAVLink datagram fuzzing: random bytes, truncated and bit-flipped packets and
valid-but-unexpected messages against the controller's :class:`fleetctl.mavlink.link.Link` (and
the vehicle proxies listening on it) and against the simulated fleet (``sitl``). Nothing may raise
out of a handler, and valid traffic still flows afterwards.
"""

from __future__ import annotations

import asyncio
import logging
import math
import random
import socket
from collections.abc import Iterator
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.mavlink.fleet import connect_fleet  # noqa: E402
from fleetctl.mavlink.link import Link, parse_url  # noqa: E402
from tests.run.ctl_helpers import mission_dict, mission_from, sim_fleet

N = 400  # datagrams per target


def _unexpected(rng: random.Random, mav: M.MAVLink, target: int) -> M.MAVLink_message:
    nan, inf = math.nan, math.inf
    f = lambda: rng.choice([0.0, -1.0, 1e38, -1e38, nan, inf, 3.5])  # noqa: E731
    i = lambda bits: rng.randrange(2**bits)  # noqa: E731
    k = rng.randrange(14)
    if k == 0:
        return mav.command_long_encode(target, rng.choice([0, 1, 190]), i(16), i(8),
                                       f(), f(), f(), f(), f(), f(), f())
    if k == 1:
        return mav.command_int_encode(target, 1, i(8), i(16), 0, 0, f(), f(), f(), f(), i(31), i(31), f())
    if k == 2:
        return mav.mission_count_encode(target, 1, i(16), rng.choice([0, 1, 2, 255]))
    if k == 3:
        return mav.mission_item_int_encode(target, 1, i(16), i(8), i(16), i(8), i(8), f(), f(), f(), f(),
                                           i(31) - 2**30, i(31) - 2**30, f(), rng.choice([0, 1, 2, 255]))
    if k == 4:
        return mav.mission_request_int_encode(target, 1, i(16), rng.choice([0, 1, 2, 255]))
    if k == 5:
        return mav.mission_ack_encode(target, 1, i(8), rng.choice([0, 1, 2, 255]))
    if k == 6:
        return mav.command_ack_encode(i(16), i(8), i(8), i(31), target, 1)
    if k == 7:
        return mav.heartbeat_encode(i(8), i(8), i(8), i(32), i(8), i(8))
    if k == 8:
        return mav.global_position_int_encode(i(32), i(31) - 2**30, i(31) - 2**30, i(31) - 2**30,
                                              i(31) - 2**30, i(15), i(15), i(15), i(16))
    if k == 9:
        return mav.sys_status_encode(i(32), i(32), i(32), i(16), i(16), i(15), rng.choice([-1, 0, 100, 127]),
                                     i(16), i(16), i(16), i(16), i(16), i(16))
    if k == 10:
        return mav.set_mode_encode(target, i(8), i(32))
    if k == 11:
        return mav.mission_current_encode(i(16))
    if k == 12:
        return mav.statustext_encode(i(8), bytes(rng.randrange(256) for _ in range(50)))
    return mav.home_position_encode(i(31), i(31), i(31), f(), f(), f(), [f()] * 4, f(), f(), f())


def datagrams(seed: int, n: int, target: int) -> Iterator[tuple[str, bytes]]:
    rng = random.Random(seed)
    for _ in range(n):
        mav = M.MAVLink(None, srcSystem=rng.choice([1, 11, 12, 42, 255, 0]),
                        srcComponent=rng.choice([1, 190]))
        packet = bytes(_unexpected(rng, mav, rng.choice([0, target, 99])).pack(mav))
        kind = rng.choice(["random", "truncated", "bitflip", "unexpected", "concat"])
        if kind == "random":
            yield kind, bytes(rng.randrange(256) for _ in range(rng.randint(0, 300)))
        elif kind == "truncated":
            yield kind, packet[:rng.randrange(len(packet))]
        elif kind == "bitflip":
            b = bytearray(packet)
            for _ in range(rng.randint(1, 3)):
                b[rng.randrange(len(b))] ^= 1 << rng.randrange(8)
            yield kind, bytes(b)
        elif kind == "concat":
            yield kind, packet * rng.randint(2, 5) + b"\xfd" + bytes(rng.randrange(256) for _ in range(9))
        else:
            yield kind, packet


class NoHandlerErrors(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.ERROR)
        self.records: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(self.format(record))


@pytest.fixture
def log_errors() -> Iterator[NoHandlerErrors]:
    h = NoHandlerErrors()
    logging.getLogger().addHandler(h)
    yield h
    logging.getLogger().removeHandler(h)


async def test_link_survives_fuzzed_datagrams(log_errors: NoHandlerErrors) -> None:
    async with Link("udpin://127.0.0.1:0", heartbeat_hz=5.0) as link:
        seen: list[str] = []
        link.subscribe(lambda m: seen.append(m.get_type()))
        port = link.local_port
        assert port is not None
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for _, d in datagrams(1, N, target=255):
                s.sendto(d, ("127.0.0.1", port))
            await asyncio.sleep(0.2)
            assert link.rx_bad > 0 and link.is_open
            mav = M.MAVLink(None, srcSystem=77, srcComponent=1)
            fut = link.expect("HEARTBEAT", sysid=77)
            s.sendto(bytes(mav.heartbeat_encode(2, 12, 0, 0, 4, 3).pack(mav)), ("127.0.0.1", port))
            hb = await asyncio.wait_for(fut, 5)
            assert hb.get_srcSystem() == 77
    assert not log_errors.records, log_errors.records[:3]


async def test_fleet_and_sim_survive_fuzzed_datagrams(tmp_path: Path, log_errors: NoHandlerErrors) -> None:
    d = mission_dict(rovers=2)
    async with sim_fleet(d) as sim:
        url = sim.endpoints["carrier"]
        a = parse_url(url)
        # the simulated fleet: junk straight at its UDP endpoint
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for _, dg in datagrams(2, N, target=11):
                s.sendto(dg, (a.host, a.port))
        await asyncio.sleep(0.3)
        mission = mission_from(d, tmp_path)
        async with await connect_fleet(mission, sim.endpoints, timeout=5.0) as fleet:
            link = next(iter(fleet.links.values()))
            peer = link.routes.get(11)
            assert peer is not None
            # the controller: junk as if it came from the vehicles' address (vehicle proxies see it)
            for _, dg in datagrams(3, N, target=255):
                link._received(dg, peer)
            await asyncio.sleep(0.3)
            # valid traffic still flows both ways
            r1 = fleet.rovers["r1"]
            await r1.wait_heartbeat(5.0)
            ack = await link.command(11, M.MAV_CMD_REQUEST_MESSAGE, (M.MAVLINK_MSG_ID_AUTOPILOT_VERSION,))
            assert ack.accepted
        assert sim.errors == 0, sim.last_error
    assert not [r for r in log_errors.records if "error handling" in r or "handler failed" in r], \
        log_errors.records[:3]


async def test_truncated_datagram_does_not_swallow_the_next_one() -> None:
    """Found by the fuzzer: a truncated datagram left a partial message in the peer's parser, which
    then ate the start of the next good datagram from that peer (the heartbeat never arrived)."""
    async with Link("udpin://127.0.0.1:0", heartbeat_hz=5.0) as link:
        mav = M.MAVLink(None, srcSystem=78, srcComponent=1)
        good = bytes(mav.heartbeat_encode(2, 12, 0, 0, 4, 3).pack(mav))
        fut = link.expect("HEARTBEAT", sysid=78)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.sendto(good[:7], ("127.0.0.1", link.local_port))
            await asyncio.sleep(0.05)
            s.sendto(good, ("127.0.0.1", link.local_port))
            assert (await asyncio.wait_for(fut, 5)).get_srcSystem() == 78
