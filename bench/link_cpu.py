"""CPU per received message: fleetctl's :class:`~fleetctl.mavlink.link.Link` vs a bare pymavlink
decode loop on the same datagrams.

Traffic per vehicle and simulated second: 10 GLOBAL_POSITION_INT and 1 each of HEARTBEAT,
SYS_STATUS, BATTERY_STATUS, EXTENDED_SYS_STATE, MISSION_CURRENT and GPS_RAW_INT, bundled into
datagrams of at most 1200 bytes the way the simulated fleet's endpoint does (all vehicles of a link
behind one address, as rovers sharing their carrier's radio). The vehicles sit on links of at most
``--per-link`` vehicles each (system ids 1.. on every link, as a mission of several carriers on
links of their own numbers them): 400 vehicles are 4 links of 100 with the same system ids. The
datagrams of all links are fed in time order straight into their link's ``datagram_received`` (no
sockets: what is measured is decoding and dispatch), with one subscriber per vehicle system id on
its link (as each :class:`~fleetctl.mavlink.vehicle.Vehicle` proxy subscribes) whose handler
counts; the bare loop is one pymavlink parser per link, ``parser.parse_buffer(datagram)`` and a
loop over the messages. ``--signed`` adds rows where every message is signed and the link checks
each signature (the bare loop then decodes the same signed datagrams without checking them).

    python bench/link_cpu.py [--vehicles 100,200,400] [--per-link 100] [--seconds 5] [--repeat 5] [--signed]

Prints a markdown table; the ratio is link CPU / bare decoding CPU (best of ``--repeat`` interleaved
runs each). Signed rows also time the bare loop with pymavlink's own signature check, which is
what checking signatures costs without fleetctl.
"""

from __future__ import annotations

import argparse
import gc
import math
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pymavlink.dialects.v20 import ardupilotmega as M  # noqa: E402

from fleetctl.mavlink.link import Link  # noqa: E402
from fleetctl.mavlink.signing import SigningKey  # noqa: E402

MAX_DATAGRAM = 1200
TICK_HZ = 50
ADDR = ("127.0.0.1", 14555)
KEY = SigningKey(bytes(range(32)))


Datagrams = list[tuple[int, bytes]]  # (link index, datagram) in time order


def traffic(n: int, per_link: int, seconds: float, signed: bool) -> tuple[Datagrams, int]:
    """Datagrams of ``seconds`` of ``n`` vehicles' telemetry on links of ``per_link`` vehicles,
    and the number of messages."""
    mavs = []
    for k in range(n):
        mav = M.MAVLink(None, srcSystem=k % per_link + 1, srcComponent=1)
        if signed:
            mav.signing.secret_key = KEY.secret
            mav.signing.sign_outgoing = True
            mav.signing.timestamp = 1_000_000_000 + k
            mav.signing.link_id = k // per_link
        mavs.append(mav)
    datagrams: Datagrams = []
    count = 0
    for tick in range(int(seconds * TICK_HZ)):
        bufs: dict[int, bytearray] = {}
        for k, mav in enumerate(mavs):
            li = k // per_link
            for data in _due(mav, k, tick):
                count += 1
                buf = bufs.setdefault(li, bytearray())
                if buf and len(buf) + len(data) > MAX_DATAGRAM:
                    datagrams.append((li, bytes(buf)))
                    buf = bufs[li] = bytearray()
                buf += data
        datagrams += [(li, bytes(buf)) for li, buf in bufs.items() if buf]
    return datagrams, count


def _due(mav: Any, k: int, tick: int) -> list[bytes]:
    """The messages vehicle ``k`` sends at ``tick``, packed."""
    t = tick / TICK_HZ
    phase = (k * 7) % TICK_HZ
    msgs: list[Any] = []
    if (tick + phase) % (TICK_HZ // 10) == 0:
        msgs.append(mav.global_position_int_encode(int(t * 1000), 473977420 + k, 85455940 + k,
                                                   488000, 5000, 120, -40, 0, 9000))
    if (tick + phase) % TICK_HZ == 0:
        msgs += [
            mav.heartbeat_encode(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_PX4, 209, 0x04030000, 4),
            mav.sys_status_encode(1, 1, 1, 100, 16000, -1, 90, 0, 0, 0, 0, 0, 0),
            mav.battery_status_encode(0, 0, 1, 0x7FFF, [4000] * 4 + [0xFFFF] * 6, -1, -1, -1, 90, 0, 1),
            mav.extended_sys_state_encode(0, M.MAV_LANDED_STATE_IN_AIR),
            mav.mission_current_encode(3, 7, 3, 1),
            mav.gps_raw_int_encode(int(t * 1e6), 3, 473977420 + k, 85455940 + k, 488000, 80, 120,
                                   500, 9000, 14),
        ]
    out = []
    for m in msgs:
        out.append(bytes(m.pack(mav)))
        mav.seq = (mav.seq + 1) & 0xFF
    return out


def bare(datagrams: Datagrams, links: int, verify: bool = False) -> tuple[float, int]:
    """CPU of one pymavlink parser per link decoding the datagrams; ``verify``: with pymavlink's own
    signature check (its ``signing.secret_key`` set). Returns the CPU and the messages decoded."""
    parsers = [M.MAVLink(None) for _ in range(links)]
    for p in parsers:
        p.robust_parsing = True
        if verify:
            p.signing.secret_key = KEY.secret
    t0 = time.process_time()
    n = 0
    for li, d in datagrams:
        for m in parsers[li].parse_buffer(d) or []:
            n += m.get_type() != "BAD_DATA"
    return time.process_time() - t0, n


def link(datagrams: Datagrams, n: int, per_link: int, signed: bool) -> tuple[float, list[Link], list[int]]:
    """CPU of the links on the datagrams; the links and, per vehicle, the messages its subscriber got."""
    lks = []
    for li in range((n + per_link - 1) // per_link):
        lk = Link(f"udp://127.0.0.1:{14555 + li}", signing_key=KEY if signed else None, link_id=li,
                  signing_state=False)
        if signed:  # the bench's vehicles' clocks are far in the past: accept their first timestamps
            lk._verifier.max_behind = 1 << 47  # type: ignore[union-attr]
        lks.append(lk)
    handled = [0] * n

    def handler_of(k: int) -> Any:
        def handler(_msg: Any) -> None:
            handled[k] += 1

        return handler

    for k in range(n):
        lks[k // per_link].subscribe(handler_of(k), sysid=k % per_link + 1)
    received = [lk._received for lk in lks]
    t0 = time.process_time()
    for li, d in datagrams:
        received[li](d, ADDR)
    elapsed = time.process_time() - t0
    assert all(lk.rx_bad == 0 for lk in lks), [lk.rx_bad for lk in lks]
    return elapsed, lks, handled


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vehicles", default="100,200,400")
    ap.add_argument("--per-link", type=int, default=100, help="vehicles per link (system ids 1.. on each)")
    ap.add_argument("--seconds", type=float, default=5.0, help="simulated seconds of traffic per run")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--signed", action="store_true", help="also measure signed traffic")
    args = ap.parse_args()
    if not 1 <= args.per_link <= 254:
        ap.error("--per-link: 1 .. 254 vehicles (system ids on one link)")
    rows = []
    for signed in (False, True) if args.signed else (False,):
        for n in (int(x) for x in args.vehicles.split(",")):
            datagrams, count = traffic(n, args.per_link, args.seconds, signed)
            links = (n + args.per_link - 1) // args.per_link
            gc.collect()
            tb = tv = tl = float("inf")
            for _ in range(args.repeat):  # interleaved, so all see the same load on a shared machine
                t, decoded = bare(datagrams, links)
                tb = min(tb, t)
                if signed:
                    t, verified = bare(datagrams, links, verify=True)
                    tv = min(tv, t)
                    assert verified == count, (verified, count)
                t, lks, handled = link(datagrams, n, args.per_link, signed)
                tl = min(tl, t)
            assert decoded == count == sum(lk.rx_messages for lk in lks) == sum(handled), count
            per_vehicle = count // n
            assert all(abs(h - per_vehicle) <= 12 for h in handled), "a vehicle got another's messages"
            if signed:
                assert all(sum(lk.rejected.values()) == 0 for lk in lks)
            kind = "signed" if signed else "unsigned"
            rows.append((n, links, kind, count / args.seconds, count, tb, tv, tl))
    print(f"python {sys.version.split()[0]}, {args.seconds:g} s of traffic per run, best of {args.repeat}\n")
    print("| vehicles | links | traffic | msg/s (per sim s) | bare decode µs/msg "
          "| bare + pymavlink signature check µs/msg | Link µs/msg | Link / bare decode |")
    print("|---:|---:|---|---:|---:|---:|---:|---:|")
    for n, links, kind, rate, count, tb, tv, tl in rows:
        verify = f"{tv / count * 1e6:.2f}" if math.isfinite(tv) else "-"
        print(f"| {n} | {links} | {kind} | {rate:,.0f} | {tb / count * 1e6:.2f} | {verify} | "
              f"{tl / count * 1e6:.2f} | {tl / tb:.2f}x |")


if __name__ == "__main__":
    main()
