"""Long operations flown through the simulated fleet: planned against flown operation time.

Random instances (seeded): n rovers and 2–3 × n tasks in a square of ``--side`` metres (heights
2–8 m; a third of the tasks worked landed), 30–120 s of work each, the carrier starting at a corner
(10 m/s, 2 m/s², 1 rad/s, 2 s unloading and loading, 10 s per battery swap), rovers at 5 m/s and
3 m/s², 80 m launch flights, 240 s batteries with a 10 % reserve (so that rovers come back for
swaps). Each is written as a mission file and flown end to end by ``fleetctl.run.flight.execute``
(``run``) on the embedded simulated fleet (real UDP) at ``--speedup``; the operation times are in
simulated seconds: planned = the plan's makespan, flown = the carrier's route start to the last
rover loaded. Also: the sorties and swaps flown, and whether the run ended complete (every task
done, every rover on the deck).

    python bench/operations_flown.py [--reps 6] [--rovers 2,3] [--speedup 20] [--side 160]

Prints a markdown table.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import logging
import random
import statistics
import sys
import tempfile
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fleetctl.mission import load_mission  # noqa: E402
from fleetctl.run.flight import execute  # noqa: E402

ORIGIN = {"lat": 47.397742, "lon": 8.545594, "alt": 488.0}


def mission(seed: int, rovers: int, side: float, speedup: float) -> dict[str, Any]:
    rng = random.Random(seed)
    n = rovers * rng.randint(2, 3)
    tasks = []
    for i in range(n):
        ground = rng.random() < 1 / 3
        x, y = round(rng.uniform(0, side), 1), round(rng.uniform(0, side), 1)
        z = 0.0 if ground else round(rng.uniform(2, 8), 1)
        tasks.append({"id": f"t{i + 1}", "position": [x, y, z], "duration": round(rng.uniform(30, 120), 1),
                      "work": "ground" if ground else "hover"})
    return {
        "name": f"flown-{seed}", "origin": ORIGIN, "operation": True,
        "carrier": {"id": "carrier", "connection": "sim", "sysid": 1, "position": [0, 0], "heading_deg": 45,
                    "max_speed": 10.0, "accel": 2.0, "turn_rate": 1.0, "unload_time": 2.0, "load_time": 2.0,
                    "swap_time": 10.0},
        "rovers": {"max_speed": 5.0, "accel": 3.0, "deploy_range": 80.0, "endurance_range": 1200.0,
                   "reserve": 0.1, "fleet": {"count": rovers, "sysid_start": 11}},
        "tasks": tasks, "dwell": 60.0, "sim": {"speedup": speedup, "faults": []},
        "planner": {"seed": seed},
    }


async def fly(d: dict[str, Any], folder: Path) -> dict[str, Any]:
    path = folder / f"{d['name']}.yaml"
    path.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
    out = await execute(load_mission(path), "run", run_dir=folder / d["name"], force=True)
    s = out.summary
    kinds = [json.loads(line)["kind"] for line in Path(s["journal"]).read_text().splitlines()]
    return {"planned": s["makespan_planned"], "flown": s["makespan_flown"], "result": s["result"],
            "tasks": len(d["tasks"]), "done": len(s["tasks_done"]), "sorties": kinds.count("sortie_launched"),
            "swaps": kinds.count("battery_swapped"), "replans": s["replans"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reps", type=int, default=6)
    ap.add_argument("--rovers", default="2,3")
    ap.add_argument("--speedup", type=float, default=20.0)
    ap.add_argument("--side", type=float, default=160.0)
    args = ap.parse_args()
    logging.basicConfig(level=logging.ERROR)
    print(f"speedup {args.speedup:g}, {args.side:g} m square\n")
    print("| instance | rovers | tasks | sorties | swaps | replans | planned s | flown s | flown / planned "
          "| result |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    ratios: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        for rovers in (int(x) for x in args.rovers.split(",")):
            for rep in range(args.reps):
                seed = 1000 * rovers + rep
                r = asyncio.run(fly(mission(seed, rovers, args.side, args.speedup), Path(tmp)))
                ratio = r["flown"] / r["planned"] if r["flown"] and r["planned"] else float("nan")
                if r["flown"]:
                    ratios.append(ratio)
                print(f"| {seed} | {rovers} | {r['tasks']} | {r['sorties']} | {r['swaps']} | {r['replans']} "
                      f"| {r['planned']:.1f} | {r['flown'] or float('nan'):.1f} | {ratio:.3f} "
                      f"| {r['result']} ({r['done']}/{r['tasks']} done) |", flush=True)
    if ratios:
        print(f"\nflown / planned over {len(ratios)} complete runs: mean {statistics.mean(ratios):.3f}, "
              f"largest {max(ratios):.3f}")


if __name__ == "__main__":
    main()
