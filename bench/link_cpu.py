"""CPU per received message: fleetctl's :class:`~fleetctl.mavlink.link.Link` vs a bare pymavlink
decode loop on the same datagrams.

Traffic per vehicle and simulated second: 10 GLOBAL_POSITION_INT and 1 each of HEARTBEAT,
SYS_STATUS, BATTERY_STATUS, EXTENDED_SYS_STATE, MISSION_CURRENT and GPS_RAW_INT, bundled into
datagrams of at most 1200 bytes the way the simulated fleet's endpoint does (all vehicles behind
one address, as rovers sharing the carrier's radio). The datagrams are fed straight into the
link's ``datagram_received`` (no sockets: what is measured is decoding and dispatch), with one
subscriber per vehicle system id (as each :class:`~fleetctl.mavlink.vehicle.Vehicle` proxy
subscribes) whose handler does nothing; the bare loop is ``parser.parse_buffer(datagram)`` and a
loop over the messages. ``--signed`` adds rows where every message is signed and the link checks
each signature (the bare loop then decodes the same signed datagrams without checking them).

    python bench/link_cpu.py [--vehicles 50,100,200] [--seconds 5] [--repeat 5] [--signed]

Prints a markdown table; the ratio is link CPU / bare CPU (best of ``--repeat`` interleaved runs each).
"""

from __future__ import annotations

import argparse
import gc
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


def traffic(n: int, seconds: float, signed: bool) -> tuple[list[bytes], int]:
    """Datagrams of ``seconds`` of ``n`` vehicles' telemetry, and the number of messages."""
    mavs = []
    for k in range(n):
        mav = M.MAVLink(None, srcSystem=k + 1, srcComponent=1)
        if signed:
            mav.signing.secret_key = KEY.secret
            mav.signing.sign_outgoing = True
            mav.signing.timestamp = 1_000_000_000 + k
        mavs.append(mav)
    datagrams: list[bytes] = []
    count = 0
    ticks = int(seconds * TICK_HZ)
    for tick in range(ticks):
        t = tick / TICK_HZ
        buf = bytearray()
        for k, mav in enumerate(mavs):
            phase = (k * 7) % TICK_HZ
            msgs: list[Any] = []
            if (tick + phase) % (TICK_HZ // 10) == 0:
                msgs.append(mav.global_position_int_encode(int(t * 1000), 473977420 + k, 85455940 + k,
                                                           488000, 5000, 120, -40, 0, 9000))
            if (tick + phase) % TICK_HZ == 0:
                msgs += [
                    mav.heartbeat_encode(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_PX4, 209, 0x04030000, 4),
                    mav.sys_status_encode(1, 1, 1, 100, 16000, -1, 90, 0, 0, 0, 0, 0, 0),
                    mav.battery_status_encode(0, 0, 1, 0x7FFF, [4000] * 4 + [0xFFFF] * 6, -1, -1, -1, 90, 0,
                                              1),
                    mav.extended_sys_state_encode(0, M.MAV_LANDED_STATE_IN_AIR),
                    mav.mission_current_encode(3, 7, 3, 1),
                    mav.gps_raw_int_encode(int(t * 1e6), 3, 473977420 + k, 85455940 + k, 488000, 80, 120,
                                           500, 9000, 14),
                ]
            for m in msgs:
                data = m.pack(mav)
                mav.seq = (mav.seq + 1) & 0xFF
                count += 1
                if buf and len(buf) + len(data) > MAX_DATAGRAM:
                    datagrams.append(bytes(buf))
                    buf = bytearray()
                buf += data
        if buf:
            datagrams.append(bytes(buf))
    return datagrams, count


def bare(datagrams: list[bytes]) -> float:
    parser = M.MAVLink(None)
    parser.robust_parsing = True
    t0 = time.process_time()
    for d in datagrams:
        for _m in parser.parse_buffer(d) or []:
            pass
    return time.process_time() - t0


def link(datagrams: list[bytes], n: int, signed: bool) -> tuple[float, Link]:
    lk = Link("udp://127.0.0.1:14555", signing_key=KEY if signed else None, signing_state=False)
    if signed:  # the bench's vehicles' clocks are far in the past: accept their first timestamps
        lk._verifier.max_behind = 1 << 47  # type: ignore[union-attr]
    handled = [0]

    def handler(_msg: Any) -> None:
        handled[0] += 1

    for k in range(n):
        lk.subscribe(handler, sysid=k + 1)
    t0 = time.process_time()
    for d in datagrams:
        lk._received(d, ADDR)
    elapsed = time.process_time() - t0
    assert lk.rx_bad == 0, lk.rx_bad
    return elapsed, lk


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vehicles", default="50,100,200")
    ap.add_argument("--seconds", type=float, default=5.0, help="simulated seconds of traffic per run")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--signed", action="store_true", help="also measure signed traffic")
    args = ap.parse_args()
    rows = []
    for signed in (False, True) if args.signed else (False,):
        for n in (int(x) for x in args.vehicles.split(",")):
            datagrams, count = traffic(n, args.seconds, signed)
            gc.collect()
            tb = tl = float("inf")
            for _ in range(args.repeat):  # interleaved, so both see the same load on a shared machine
                tb = min(tb, bare(datagrams))
                t, lk = link(datagrams, n, signed)
                tl = min(tl, t)
            assert lk.rx_messages == count, (lk.rx_messages, count)
            if signed:
                assert sum(lk.rejected.values()) == 0, lk.rejected
            rows.append((n, "signed" if signed else "unsigned", count / args.seconds, count, tb, tl))
    print(f"python {sys.version.split()[0]}, {args.seconds:g} s of traffic per run, best of {args.repeat}\n")
    print("| vehicles | traffic | msg/s (per sim s) | bare decode µs/msg | Link µs/msg | ratio |")
    print("|---:|---|---:|---:|---:|---:|")
    for n, kind, rate, count, tb, tl in rows:
        print(f"| {n} | {kind} | {rate:,.0f} | {tb / count * 1e6:.2f} | {tl / count * 1e6:.2f} | "
              f"{tl / tb:.2f}x |")


if __name__ == "__main__":
    main()
