"""How far does the simulated fleet scale? 1 carrier + N rovers, all flying, every vehicle
streaming GLOBAL_POSITION_INT at 10 Hz (plus the default 1 Hz streams) on the carrier's link.

The fleet runs in a child process, which measures its own CPU share (``time.process_time`` over
wall time) and whether simulated time keeps up with ``speedup`` x wall time; this process is the
ground station, counting the position messages it receives per vehicle.

    python bench/sim_scale.py [--rovers 10,50,100,200] [--seconds 8] [--speedup 1] [--json OUT]

Prints a markdown table.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import multiprocessing as mp
import socket
import time
from typing import Any

ORIGIN = (47.397742, 8.545594, 488.0)


def _fleet_process(n: int, speedup: float, warmup: float, seconds: float, conn: Any) -> None:
    from sitl import FleetConfig, SimFleet, VehicleSpec

    async def main() -> None:
        rovers = [VehicleSpec(id=f"r{k + 1}", sysid=11 + k, role="rover", max_speed=1.0, accel=0.5,
                              endurance_range=1e6) for k in range(n)]
        carrier = VehicleSpec(id="carrier", sysid=1, role="carrier", max_speed=15.0, accel=10.0,
                              turn_rate=3.0, connection="sim", position=(0.0, 0.0, 0.0), frame="ground")
        cfg = FleetConfig(origin=ORIGIN, carrier=carrier, rovers=rovers, speedup=speedup, position_hz=10.0)
        async with SimFleet(cfg) as fleet:
            conn.send(fleet.endpoints["carrier"])
            for k, r in enumerate(rovers):  # every rover flies away on its own heading
                fleet.vehicle(r.id).arm()
                a = 2 * math.pi * k / max(n, 1)
                fleet.rover(r.id).goto(5000 * math.cos(a), 5000 * math.sin(a), 10.0 + k % 7)
            fleet.vehicle("carrier").arm()
            fleet.body("carrier").goto(3000.0, 0.0)
            await asyncio.sleep(warmup)
            c0, w0, s0 = time.process_time(), time.monotonic(), fleet.sim_time
            tx0 = fleet.link_stats()["tx_messages"]
            await asyncio.sleep(seconds)
            c1, w1, s1 = time.process_time(), time.monotonic(), fleet.sim_time
            tx1 = fleet.link_stats()["tx_messages"]
            conn.send({"cpu": (c1 - c0) / (w1 - w0), "sim_rate": (s1 - s0) / ((w1 - w0) * speedup),
                       "tx_per_s": (tx1 - tx0) / (w1 - w0), "behind_s": fleet.behind, "errors": fleet.errors,
                       "airborne": sum(not fleet.rover(r.id).on_ground for r in rovers)})

    asyncio.run(main())


def run_one(n: int, speedup: float, warmup: float, seconds: float) -> dict[str, Any]:
    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    ctx = mp.get_context("spawn")
    parent, child = ctx.Pipe()
    proc = ctx.Process(target=_fleet_process, args=(n, speedup, warmup, seconds, child), daemon=True)
    proc.start()
    try:
        if not parent.poll(30):
            raise RuntimeError("the fleet process did not start")
        url = parent.recv()
        host, port = url.split("//", 1)[1].rsplit(":", 1)
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind(("127.0.0.1", 0))
        sock.settimeout(0.2)
        gcs = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
        parser = mavlink2.MAVLink(None)
        sock.sendto(gcs.heartbeat_encode(6, 8, 0, 0, 0).pack(gcs), (host, int(port)))
        counts: dict[int, int] = {}
        t_start = time.monotonic() + warmup
        t_end = t_start + seconds
        while time.monotonic() < t_end + 0.5:
            try:
                data = sock.recv(65536)
            except TimeoutError:
                continue
            now = time.monotonic()
            for m in parser.parse_buffer(data) or []:
                if m.get_type() == "GLOBAL_POSITION_INT" and t_start <= now < t_end:
                    counts[m.get_srcSystem()] = counts.get(m.get_srcSystem(), 0) + 1
        sock.close()
        if not parent.poll(30):
            raise RuntimeError("the fleet process did not report")
        res = parent.recv()
    finally:
        proc.join(timeout=10)
        if proc.is_alive():
            proc.terminate()
            proc.join(timeout=5)
    rates = [counts.get(s, 0) / seconds for s in [1, *range(11, 11 + n)]]
    res.update(rovers=n, speedup=speedup, pos_hz_min=min(rates), pos_hz_mean=sum(rates) / len(rates))
    return res


def table(rows: list[dict[str, Any]]) -> str:
    out = ["| rovers | speedup | sim CPU (% of one core) | messages sent/s "
           "| position Hz per vehicle (min / mean) | sim time / real time | keeps up |",
           "|---:|---:|---:|---:|---:|---:|:---:|"]
    for r in rows:
        keeps = r["sim_rate"] >= 0.98 and r["behind_s"] < 0.5
        out.append(f"| {r['rovers']} | {r['speedup']:g} | {100 * r['cpu']:.1f} | {r['tx_per_s']:.0f} | "
                   f"{r['pos_hz_min']:.1f} / {r['pos_hz_mean']:.1f} | {r['sim_rate']:.3f} | "
                   f"{'yes' if keeps else 'no'} |")
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rovers", default="10,50,100,200")
    ap.add_argument("--seconds", type=float, default=8.0, help="measurement window (wall seconds)")
    ap.add_argument("--warmup", type=float, default=2.0)
    ap.add_argument("--speedup", type=float, default=1.0)
    ap.add_argument("--json", default=None, help="also write the rows as JSON here")
    args = ap.parse_args()
    rows = [run_one(int(n), args.speedup, args.warmup, args.seconds) for n in args.rovers.split(",")]
    print(table(rows))
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(rows, fh, indent=2)


if __name__ == "__main__":
    main()
