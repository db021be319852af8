"""Planned vs flown makespan of the dissertation's scenarios through the simulated fleet, and the
controller's CPU share with 100 rovers.

1. Every ``missions/paper/deploy_*.yaml`` (and a few ``collect_*.yaml``) is flown by
   ``fleetctl.executor.execute`` against the in-process simulated fleet (real UDP, ``--speedup``);
   flown makespan is measured in *simulated* seconds (``SimFleet.sim_time``). The scenario files
   have no ``origin`` (the planners work in ENU), so one is added for the MAVLink coordinates.
2. A generated mission with 100 tasks and 100 rovers is deployed with the simulated fleet in a
   child process (so the two do not share a CPU account); the controller's CPU share is
   ``time.process_time()`` over wall time during the flight.

    python bench/flight.py [--speedup 20] [--cpu-speedup 5] [--only deploy_2tasks,...] [--json OUT]

Prints markdown tables.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import logging
import multiprocessing as mp
import random
import socket
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fleetctl.mission import load_mission  # noqa: E402
from fleetctl.run.runner import execute  # noqa: E402
from fleetctl.run.sim import sim_mission_dict  # noqa: E402
from sitl import FleetConfig, SimFleet  # noqa: E402

ORIGIN = {"lat": 47.397742, "lon": 8.545594, "alt": 488.0}
COLLECT = ["collect_10rovers_3d", "collect_15rovers_d15"]


def _with_origin(src: Path, tmp: Path, **extra: Any) -> Path:
    d = yaml.safe_load(src.read_text())
    d.setdefault("origin", ORIGIN)
    d.update(extra)
    out = tmp / src.name
    out.write_text(yaml.safe_dump(d, sort_keys=False))
    return out


async def _fly(path: Path, command: str, speedup: float, runs: Path) -> dict[str, Any]:
    mission = load_mission(path)
    raw = sim_mission_dict(mission, command)
    cfg = FleetConfig.from_mission_dict(raw, speedup=speedup)
    t = time.perf_counter()
    async with SimFleet(cfg) as sim:
        if command == "collect":
            rp = mission.rovers
            for cr in mission.collection or ():
                sim.rover(cr.id).battery = min(1.0, rp.reserve + cr.range / rp.endurance_range)
        out = await execute(mission, command, sim=sim, runs_dir=runs)
    s = out.summary
    n = len(mission.tasks) if command == "deploy" else len(mission.collection or ())
    plan = json.loads((out.run_dir / "plan.json").read_text())
    return {"mission": path.stem, "kind": command, "n": n, "stops": len(plan["stops"]),
            "planned": s["makespan_planned"], "flown": s["makespan_flown"], "result": s["result"],
            "wall": time.perf_counter() - t, "error": out.error}


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _hundred(tmp: Path, port: int, speedup: float) -> Path:
    rng = random.Random(7)
    tasks = [{"id": f"t{i + 1}", "position": [round(rng.uniform(0, 300), 1), round(rng.uniform(0, 300), 1),
                                              round(rng.uniform(2, 10), 1)]} for i in range(100)]
    d = {
        "name": "bench100", "origin": ORIGIN,
        "carrier": {"id": "carrier", "connection": f"udp://127.0.0.1:{port}", "sysid": 1, "position": [0, 0],
                    "heading_deg": 45, "max_speed": 15.0, "accel": 10.0, "turn_rate": 3.0, "unload_time": 4.0,
                    "load_time": 4.0},
        "rovers": {"max_speed": 2.0, "accel": None, "deploy_range": 25.0, "endurance_range": 100.0,
                   "reserve": 0.1, "fleet": {"count": 100, "sysid_start": 11}},
        "tasks": tasks, "sim": {"speedup": speedup, "faults": []}, "links": {"heartbeat_timeout": 5.0},
    }
    path = tmp / "bench100.yaml"
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    return path


def _sim_process(path: str, ready: Any, stop: Any, result: Any) -> None:
    async def main() -> None:
        cfg = FleetConfig.from_mission_dict(yaml.safe_load(Path(path).read_text()))
        async with SimFleet(cfg) as sim:
            w0, c0 = time.perf_counter(), time.process_time()
            ready.set()
            while not stop.is_set():
                await asyncio.sleep(0.2)
            cpu = (time.process_time() - c0) / (time.perf_counter() - w0)
            result.put({"sim_time": sim.sim_time, "cpu": cpu})

    asyncio.run(main())


async def _cpu_share(tmp: Path, speedup: float) -> dict[str, Any]:
    path = _hundred(tmp, _free_port(), speedup)
    ctx = mp.get_context("spawn")
    ready, stop, result = ctx.Event(), ctx.Event(), ctx.Queue()
    proc = ctx.Process(target=_sim_process, args=(str(path), ready, stop, result), daemon=True)
    proc.start()
    try:
        if not await asyncio.to_thread(ready.wait, 60):
            raise RuntimeError("the simulated fleet did not start")
        mission = load_mission(path)
        w0, c0 = time.perf_counter(), time.process_time()
        t0 = time.monotonic()
        # the fleet runs elsewhere: mission time ~ wall x speedup
        out = await execute(mission, "deploy", runs_dir=tmp / "runs", connect_timeout=20.0,
                            clock_speedup=speedup)
        wall = time.perf_counter() - w0
        cpu = time.process_time() - c0
        stop.set()
        sim = await asyncio.to_thread(result.get, True, 30)
    finally:
        stop.set()
        await asyncio.to_thread(proc.join, 10)
        if proc.is_alive():
            proc.kill()
    s = out.summary
    return {"rovers": 100, "tasks": len(mission.tasks), "result": s["result"],
            "planned": s["makespan_planned"], "flown": s["makespan_flown"], "wall": wall,
            "controller_cpu": cpu / wall, "sim_cpu": sim["cpu"],
            "speedup": speedup, "elapsed": time.monotonic() - t0}


def _fmt(v: Any, nd: int = 1) -> str:
    if v is None:
        return "–"
    if isinstance(v, float):
        return f"{v:.{nd}f}"
    return str(v)


async def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--speedup", type=float, default=20.0, help="sim speedup of the scenario flights")
    ap.add_argument("--cpu-speedup", type=float, default=5.0, help="sim speedup of the 100-rover flight")
    ap.add_argument("--only", help="comma-separated mission stems")
    ap.add_argument("--no-cpu", action="store_true", help="skip the 100-rover CPU measurement")
    ap.add_argument("--json", help="write the rows as JSON here")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.ERROR)
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        paper = ROOT / "missions" / "paper"
        jobs = [(p, "deploy") for p in sorted(paper.glob("deploy_*.yaml"))]
        jobs += [(paper / f"{c}.yaml", "collect") for c in COLLECT]
        if args.only:
            keep = set(args.only.split(","))
            jobs = [j for j in jobs if j[0].stem in keep]
        for src, kind in jobs:
            rows.append(await _fly(_with_origin(src, tmp), kind, args.speedup, tmp / "runs"))
            r = rows[-1]
            print(f"  {r['mission']}: {r['result']} planned {_fmt(r['planned'])} flown {_fmt(r['flown'])}"
                  + (f" ({r['error']})" if r["error"] else ""), file=sys.stderr)
        cpu = None if args.no_cpu else await _cpu_share(tmp, args.cpu_speedup)
    print(f"\n### Planned vs flown makespan (simulated seconds, sim speedup {args.speedup:g}x)\n")
    print("| mission | kind | n | stops | planned s | flown s | flown − planned | % | result | wall s |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---|---:|")
    for r in rows:
        d = None if r["flown"] is None else r["flown"] - r["planned"]
        pct = None if d is None or not r["planned"] else 100 * d / r["planned"]
        print(f"| {r['mission']} | {r['kind']} | {r['n']} | {r['stops']} | {_fmt(r['planned'])} | "
              f"{_fmt(r['flown'])} | {_fmt(d)} | {_fmt(pct)} | {r['result']} | {_fmt(r['wall'])} |")
    if cpu is not None:
        print(f"\n### Controller CPU share, 100 rovers (simulated fleet in a child process, "
              f"{cpu['speedup']:g}x)\n")
        print("| rovers | tasks | result | planned s | flown s | wall s | controller CPU | sim CPU |")
        print("|---:|---:|---|---:|---:|---:|---:|---:|")
        print(f"| {cpu['rovers']} | {cpu['tasks']} | {cpu['result']} | {_fmt(cpu['planned'])} | "
              f"{_fmt(cpu['flown'])} | {_fmt(cpu['wall'])} | {100 * cpu['controller_cpu']:.0f} % | "
              f"{100 * cpu['sim_cpu']:.0f} % |")
    if args.json:
        Path(args.json).write_text(json.dumps({"flights": rows, "cpu": cpu}, indent=1))


if __name__ == "__main__":
    asyncio.run(main())
