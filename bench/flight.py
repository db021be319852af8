"""Planned vs flown makespan of the dissertation's scenarios and recon through the simulated fleet,
the lowest battery any rover reached, and the controller's CPU share with 100 rovers.

1. Every ``missions/paper/*.yaml`` with tasks gets a deploy row, every one with a ``collection:``
   section a collect row, and ``missions/recon.yaml`` both; each is flown by
   ``fleetctl.run.flight.execute`` against the in-process simulated fleet (real UDP) at every
   ``--speedup`` given (default 1 and 20). Flown makespan is measured in *simulated* seconds. The
   scenario files have no ``origin`` (the planners work in ENU), so one is added for the MAVLink
   coordinates. The lowest battery is polled from the simulated rovers during the flight (a
   rover burns its battery per second in the air, hovering included); in a collect row each rover
   has ``reserve + range / endurance_range`` of its battery once the fleet is connected, as the
   scenario gives it (the runner sets it). "ETA error" is the largest gap between the live makespan
   prediction at a stop (journal `eta` records) and the flown makespan, from the first stop on.
   Rows run in ``--jobs`` child processes at once (each flight is mostly waiting at speedup 1).
2. A generated mission with 100 tasks and 100 rovers is deployed with the simulated fleet in a
   child process (so the two do not share a CPU account); the controller's CPU share is
   ``time.process_time()`` over wall time during the flight.

    python bench/flight.py [--speedup 1,20] [--jobs 6] [--cpu-speedup 5] [--only recon,...] [--no-cpu]
                           [--json OUT]

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
from fleetctl.run.flight import execute  # noqa: E402
from fleetctl.run.sim import sim_mission_dict  # noqa: E402
from sitl import FleetConfig, SimFleet  # noqa: E402

ORIGIN = {"lat": 47.397742, "lon": 8.545594, "alt": 488.0}
RUN_DWELL = 30.0  # s on task in the recon "run" row (fleetctl run --dwell 30)


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
    lowest = {"battery": 1.0}
    async with SimFleet(cfg) as sim:
        async def watch() -> None:
            while True:
                lowest["battery"] = min([lowest["battery"], *(r.battery for r in sim.world.rovers.values())])
                await asyncio.sleep(0.05)

        poll = asyncio.ensure_future(watch())
        try:
            extra = {"dwell": RUN_DWELL} if command == "run" else {}
            out = await execute(mission, command, sim=sim, runs_dir=runs, **extra)
        finally:
            poll.cancel()
    s = out.summary
    n = len(mission.tasks) if command == "deploy" else len(mission.collection or ())
    plan = json.loads((out.run_dir / "plan.json").read_text())
    flown = s["makespan_flown"]
    etas = [r["eta"] for r in map(json.loads, (out.run_dir / "journal.jsonl").read_text().splitlines())
            if r.get("kind") == "eta" and r.get("eta") is not None]
    # the eta records are per phase: a whole run's makespan is not theirs
    per_phase = flown and command != "run"
    eta_err = max((abs(e - flown) / flown for e in etas), default=None) if per_phase else None
    return {"mission": path.stem, "kind": command, "speedup": speedup, "n": n, "stops": len(plan["stops"]),
            "planned": s["makespan_planned"], "flown": flown, "result": s["result"],
            "lowest_battery": lowest["battery"], "reserve": mission.rovers.reserve,
            "eta_error": eta_err, "wall": time.perf_counter() - t, "error": out.error}


def _fly_job(args: tuple[str, str, float, str]) -> dict[str, Any]:
    """One row in a child process (its own event loop, sockets and temporary run folder)."""
    src, kind, speedup, tmp = args
    logging.basicConfig(level=logging.ERROR)
    sub = Path(tempfile.mkdtemp(dir=tmp))
    try:
        return asyncio.run(_fly(_with_origin(Path(src), sub), kind, speedup, sub / "runs"))
    except Exception as exc:  # noqa: BLE001 - a failed row is reported in the table, the others go on
        return {"mission": Path(src).stem, "kind": kind, "speedup": speedup, "n": 0, "stops": 0,
                "planned": None, "flown": None, "result": "error", "lowest_battery": None,
                "reserve": None, "eta_error": None, "wall": 0.0, "error": f"{type(exc).__name__}: {exc}"}


def _jobs(only: str | None) -> list[tuple[Path, str]]:
    paper = sorted((ROOT / "missions" / "paper").glob("*.yaml")) + [ROOT / "missions" / "recon.yaml"]
    jobs = []
    for p in paper:
        d = yaml.safe_load(p.read_text())
        if d.get("tasks"):
            jobs.append((p, "deploy"))
        if d.get("collection"):
            jobs.append((p, "collect"))
    jobs.append((ROOT / "missions" / "recon.yaml", "run"))  # deploy, dwell, collect: a whole run
    if only:
        keep = set(only.split(","))
        jobs = [j for j in jobs if j[0].stem in keep]
    return jobs


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


def _print_flights(rows: list[dict[str, Any]]) -> None:
    print("| mission | kind | speedup | n | stops | planned s | flown s | Δ % | ETA error % "
          "| lowest battery % | reserve % | result | wall s |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|")
    for r in rows:
        pct = None if r["flown"] is None or not r["planned"] else 100 * (r["flown"] / r["planned"] - 1)
        low = None if r["lowest_battery"] is None else 100 * r["lowest_battery"]
        res = None if r["reserve"] is None else 100 * r["reserve"]
        eta = None if r.get("eta_error") is None else 100 * r["eta_error"]
        print(f"| {r['mission']} | {r['kind']} | {r['speedup']:g} | {r['n']} | {r['stops']} | "
              f"{_fmt(r['planned'])} | {_fmt(r['flown'])} | {_fmt(pct)} | {_fmt(eta)} | {_fmt(low)} | "
              f"{_fmt(res, 0)} | "
              f"{r['result']} | {_fmt(r['wall'])} |")
    ok = [r for r in rows if r["flown"] is not None and r["planned"]]
    if ok:
        worst = max(ok, key=lambda r: abs(r["flown"] - r["planned"]) / r["planned"])
        d = 100 * (worst["flown"] - worst["planned"]) / worst["planned"]
        below = [r for r in rows
                 if r["lowest_battery"] is not None and r["lowest_battery"] < r["reserve"] - 1e-9]
        print(f"\nworst |Δ| {abs(d):.1f} % ({worst['mission']} {worst['kind']} at {worst['speedup']:g}x); "
              f"rows with a rover below its reserve: {len(below)} of {len(rows)}; "
              f"rows not complete: {sum(r['result'] != 'complete' for r in rows)}")


async def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--speedup", default="1,20", help="comma-separated sim speedups of the scenario flights")
    ap.add_argument("--jobs", type=int, default=6, help="flights at once (child processes)")
    ap.add_argument("--cpu-speedup", type=float, default=5.0, help="sim speedup of the 100-rover flight")
    ap.add_argument("--only", help="comma-separated mission stems")
    ap.add_argument("--no-cpu", action="store_true", help="skip the 100-rover CPU measurement")
    ap.add_argument("--json", help="write the rows as JSON here")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.ERROR)
    speedups = [float(x) for x in args.speedup.split(",")]
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        work = [(str(src), kind, sp, td) for sp in speedups for src, kind in _jobs(args.only)]
        with mp.get_context("spawn").Pool(max(1, args.jobs)) as pool:
            rows = []
            for r in pool.imap(_fly_job, work):
                rows.append(r)
                print(f"  {r['mission']} {r['kind']} {r['speedup']:g}x: {r['result']} "
                      f"planned {_fmt(r['planned'])} flown {_fmt(r['flown'])}"
                      + (f" ({r['error']})" if r["error"] else ""), file=sys.stderr)
        cpu = None if args.no_cpu else await _cpu_share(tmp, args.cpu_speedup)
    print("\n### Planned vs flown makespan (simulated seconds) and the lowest battery\n")
    _print_flights(rows)
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
